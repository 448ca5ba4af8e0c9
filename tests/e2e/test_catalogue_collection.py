"""The catalogue's modules are named by clause family (``frame.py``, not ``test_frame.py``), yet
``pytest --pyargs conformance.cases`` collects every case once, and a module named on the
command line is collected once too (pytest's own collector takes it, the plugin's hook steps aside)."""

from __future__ import annotations

import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CASES = ROOT / "conformance" / "cases"


def collect(tmp_path: Path, *targets: str) -> list[str]:
    """The node ids ``pytest --co`` lists (run from elsewhere, this checkout first on the path)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run([sys.executable, "-m", "pytest", "-c", os.devnull, "--rootdir", str(tmp_path),
                           "-p", "no:cacheprovider", "--co", "-q", *targets],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return [line for line in proc.stdout.splitlines() if "::" in line]


def test_no_catalogue_module_is_named_like_a_test() -> None:
    modules = sorted(p.name for p in CASES.glob("*.py") if p.name != "__init__.py")
    assert modules and not [m for m in modules if m.startswith("test_")]


def test_every_catalogue_module_is_collected_and_no_case_twice(tmp_path: Path) -> None:
    ids = collect(tmp_path, "--pyargs", "conformance.cases")
    assert [i for i, n in Counter(ids).items() if n > 1] == []
    files = {i.split("::")[0].rpartition("/")[2] for i in ids}
    assert files == {p.name for p in CASES.glob("*.py") if p.name != "__init__.py"}


def test_a_module_named_on_the_command_line_is_collected_once(tmp_path: Path) -> None:
    whole = [i for i in collect(tmp_path, "--pyargs", "conformance.cases") if i.split("::")[0].rpartition("/")[2] == "frame.py"]
    alone = collect(tmp_path, "--pyargs", "conformance.cases.frame")
    assert alone and len(alone) == len(set(alone))
    assert [i.split("::", 1)[1] for i in alone] == [i.split("::", 1)[1] for i in whole]
