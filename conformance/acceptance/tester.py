"""The test system's identity: what an acceptance names beside the box (IEC 61850's "test system").

Suite version, and the git commit when the suite runs from a checkout (read from ``.git`` itself: no process
is started); Python, OS and host; the versions of the libraries the verdicts rest on; the clause registry's
version; the SHA-256 of the ``PROTOCOL.md`` the run judged against (the copy a wheel carries in
``conformance/_docs``, else a checkout's ``docs/``; "unavailable" when neither is there).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import platform
import socket
import sys
from pathlib import Path
from typing import Any

from .. import __version__
from ..protocol.clauses import REGISTRY_VERSION

PACKAGE = Path(__file__).resolve().parents[1]
#: the libraries whose behaviour the verdicts rest on (their distribution names)
LIBRARIES = ("hypothesis", "scapy", "crcmod-plus", "pytest", "Jinja2")
UNAVAILABLE = "unavailable"


def protocol_md() -> Path | None:
    """The PROTOCOL.md this suite judges against: the wheel's copy, else the checkout's."""
    for path in (PACKAGE / "_docs" / "PROTOCOL.md", PACKAGE.parent / "docs" / "PROTOCOL.md"):
        if path.is_file():
            return path
    return None


def _git_dir(start: Path) -> Path | None:
    dot = start / ".git"
    if dot.is_dir():
        return dot
    if dot.is_file():  # a worktree or submodule: "gitdir: PATH"
        text = dot.read_text(encoding="utf-8", errors="replace").strip()
        if text.startswith("gitdir:"):
            found = Path(text[7:].strip())
            return found if found.is_absolute() else (start / found).resolve()
    return None


def git_commit(checkout: Path = PACKAGE.parent) -> str:
    """The commit HEAD names in the checkout the suite runs from ("" when not from a checkout)."""
    git = _git_dir(checkout)
    if git is None:
        return ""
    try:
        head = (git / "HEAD").read_text(encoding="utf-8").strip()
        if not head.startswith("ref:"):
            return head
        ref = head[4:].strip()
        common = git
        if (git / "commondir").is_file():
            common = (git / (git / "commondir").read_text(encoding="utf-8").strip()).resolve()
        for base in (git, common):
            if (base / ref).is_file():
                return (base / ref).read_text(encoding="utf-8").strip()
        packed = common / "packed-refs"
        for line in packed.read_text(encoding="utf-8").splitlines() if packed.is_file() else ():
            sha, _, name = line.partition(" ")
            if name.strip() == ref:
                return sha
    except OSError:
        return ""
    return ""


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return UNAVAILABLE


def identity() -> dict[str, Any]:
    """The tester, as summary.json's ``acceptance.tester`` holds it."""
    doc = protocol_md()
    return {
        "suite": "isight-conformance",
        "version": __version__,
        "git_commit": git_commit() or UNAVAILABLE,
        "python": f"{platform.python_implementation()} {platform.python_version()}",
        "os": f"{platform.system()} {platform.release()} ({platform.machine()})",
        "host": socket.gethostname(),
        "libraries": {name: _version(name) for name in LIBRARIES},
        "clause_registry_version": REGISTRY_VERSION,
        "protocol_md_sha256": hashlib.sha256(doc.read_bytes()).hexdigest() if doc else UNAVAILABLE,
        "executable": sys.executable,
    }
