"""No tracked file carries a merge-conflict marker (a README once did, lines 593-599)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: the three marker lines git writes, built here so that this file does not hold them
MARKER = re.compile("^(" + "<" * 7 + " |" + ">" * 7 + " |" + "=" * 7 + "$)", re.M)


def _tracked() -> list[Path]:
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        pytest.skip("not a git checkout")
    return [ROOT / name for name in out.decode().split("\0") if name]


def markers(text: str) -> list[int]:
    """The 1-based line numbers of conflict markers in ``text``."""
    return [text.count("\n", 0, m.start()) + 1 for m in MARKER.finditer(text)]


def test_marker_pattern_finds_a_conflict() -> None:
    conflict = "a\n" + "<" * 7 + " HEAD\nb\n" + "=" * 7 + "\nc\n" + ">" * 7 + " main\n"
    assert markers(conflict) == [2, 4, 6]
    assert markers("=" * 7 + "  ====\nrst table\n") == []


def test_no_tracked_file_has_conflict_markers() -> None:
    found = []
    for path in _tracked():
        try:
            text = path.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue  # binary or gone from the work tree
        found += [f"{path.relative_to(ROOT)}:{line}" for line in markers(text)]
    assert not found, f"merge-conflict markers in: {', '.join(found)}"
