"""The documentation's links stay inside the repository and resolve; every document that
mentions the protocol links docs/PROTOCOL.md."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
_LINK = re.compile(r"\]\(([^)\s]+)\)")
_CODE = re.compile(r"```.*?```|`[^`\n]*`", re.S)


def _markdown_files() -> list[Path]:
    try:
        out = subprocess.run(["git", "ls-files", "*.md"], cwd=ROOT, capture_output=True, text=True, timeout=60)
        names = out.stdout.split() if out.returncode == 0 else []
    except OSError:
        names = []
    files = [ROOT / n for n in names] or [p for p in ROOT.rglob("*.md") if ".venv" not in p.parts]
    return sorted(p for p in files if p.is_file())


def _links(path: Path) -> list[str]:
    return _LINK.findall(_CODE.sub("", path.read_text(encoding="utf-8")))


def _params() -> list[object]:
    out: list[object] = []
    for p in _markdown_files():
        rel = p.relative_to(ROOT).as_posix()
        out.append(pytest.param(p, id=rel))
    return out


@pytest.mark.parametrize("path", _params())
def test_relative_links_stay_inside_the_repository_and_resolve(path: Path):
    for target in _links(path):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue  # a URL (http:, mailto:) or an anchor in the same file
        file_part = target.split("#", 1)[0]
        resolved = (path.parent / file_part).resolve()
        assert resolved.is_relative_to(ROOT), f"{path.name} links {target}, outside the repository"
        assert resolved.exists(), f"{path.name} links {target}, which does not exist"


@pytest.mark.parametrize("path", _params())
def test_a_document_that_mentions_the_protocol_links_it(path: Path):
    if path.name == "PROTOCOL.md" or "PROTOCOL.md" not in path.read_text(encoding="utf-8"):
        return
    protocol = (ROOT / "docs" / "PROTOCOL.md").resolve()
    linked = {(path.parent / t.split("#", 1)[0]).resolve() for t in _links(path) if not t.startswith("#")}
    assert protocol in linked, f"{path.relative_to(ROOT)} mentions PROTOCOL.md but does not link docs/PROTOCOL.md"


def test_anchors_into_protocol_md_exist():
    doc = (ROOT / "docs" / "PROTOCOL.md").read_text(encoding="utf-8")
    slugs = {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-")
             for h in re.findall(r"^#+ (.+)$", _CODE.sub("", doc), re.M)}
    for path in _markdown_files():
        for target in _links(path):
            file_part, _, anchor = target.partition("#")
            if not anchor or re.match(r"^[a-z]+:", target):
                continue
            if (path.parent / file_part).resolve() == (ROOT / "docs" / "PROTOCOL.md").resolve() or \
                    (not file_part and path.name == "PROTOCOL.md"):
                assert anchor in slugs, f"{path.name} links PROTOCOL.md#{anchor}, no such heading"
