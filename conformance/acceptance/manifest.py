"""``manifest.json``: every file of a package with its SHA-256 and size, and the check that recomputes them.

The manifest lists every file under the package directory (paths relative to it, ``/``-separated) but itself
and the signatures (``signatures/``: signers add them after the manifest is written; each signs the manifest).

report.html shows the manifest's own hash, in one field (``<code class="manifest-sha256">``). Its entry in the
manifest is therefore the hash of report.html with that field's 64 hex digits as zeros (as the file was when the
manifest was made); :func:`check` zeroes the field the same way, and checks that the field holds the hash of
the manifest that is there. A box's bytes never reach the page unescaped, so no text from the box can make a
second such field.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..report.summary import atomic_write_bytes

MANIFEST = "manifest.json"
SIGNATURES = "signatures"
REPORT = "report.html"
FORMAT = "isight-conformance package manifest 1"
#: the field report.html shows the manifest's hash in (64 zeros until the manifest exists)
SLOT = re.compile(rb'<code class="manifest-sha256">([0-9a-f]{64})</code>')
ZEROS = b"0" * 64
CHUNK = 1 << 20


def package_files(root: Path) -> Iterator[str]:
    """The package's files (relative, ``/``-separated, sorted), the manifest and the signatures left out."""
    found: list[str] = []
    for folder, dirs, files in os.walk(root):
        rel_dir = Path(folder).relative_to(root)
        if rel_dir == Path("."):
            dirs[:] = [d for d in dirs if d != SIGNATURES]
        for name in files:
            rel = (rel_dir / name).as_posix()
            if rel != MANIFEST:
                found.append(rel)
    return iter(sorted(found))


def _zeroed(data: bytes) -> bytes:
    return SLOT.sub(lambda m: m.group(0).replace(m.group(1), ZEROS), data, count=1)


def file_digest(root: Path, rel: str) -> tuple[str, int]:
    """(SHA-256 hex, size) of one file; report.html with its manifest-hash field zeroed."""
    path = root / rel
    if rel == REPORT:
        data = path.read_bytes()
        return hashlib.sha256(_zeroed(data)).hexdigest(), len(data)
    digest, size = hashlib.sha256(), 0
    with path.open("rb") as fh:
        while block := fh.read(CHUNK):
            digest.update(block)
            size += len(block)
    return digest.hexdigest(), size


def sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def build(root: Path, run_id: str = "") -> dict[str, Any]:
    """The manifest of the package as it is now."""
    files = []
    for rel in package_files(root):
        digest, size = file_digest(root, rel)
        files.append({"path": rel, "sha256": digest, "size": size})
    return {"format": FORMAT, "run_id": run_id, "algorithm": "sha256",
            "report_field": "report.html is hashed with its manifest-sha256 field as 64 zeros", "files": files}


def seal(root: Path, run_id: str = "") -> str:
    """Write ``manifest.json`` (atomically), then put its hash into report.html's field; the hash.

    report.html's field must still be zeros (a fresh report): the manifest records it so."""
    report = root / REPORT
    if report.is_file():  # a package sealed before (a rerun into the same directory): the field back to zeros
        data = report.read_bytes()
        if _zeroed(data) != data:
            atomic_write_bytes(report, _zeroed(data))
    text = _manifest_text(root, run_id)
    if _supersede_signatures(root, text):
        text = _manifest_text(root, run_id)
    atomic_write_bytes(root / MANIFEST, text)
    digest = hashlib.sha256(text).hexdigest()
    if report.is_file():
        data = report.read_bytes()
        filled = SLOT.sub(lambda m: m.group(0).replace(m.group(1), digest.encode()), data, count=1)
        if filled != data:
            atomic_write_bytes(report, filled)
    return digest


def _manifest_text(root: Path, run_id: str) -> bytes:
    return (json.dumps(build(root, run_id), indent=1, ensure_ascii=False) + "\n").encode("utf-8")


def _supersede_signatures(root: Path, text: bytes) -> bool:
    """A package sealed again (a run into a directory that held one): the signatures of the old manifest no longer
    sign anything; they are kept, as evidence, in ``signatures-superseded-<old manifest hash>/``, which the new
    manifest lists like any other file."""
    old, folder = root / MANIFEST, root / SIGNATURES
    if not folder.is_dir() or not old.is_file() or old.read_bytes() == text:
        return False
    folder.rename(root / f"{SIGNATURES}-superseded-{sha256_of(old)[:16]}")
    return True


@dataclass(frozen=True)
class Problem:
    kind: str  # "changed", "added", "removed", "report-field"
    path: str
    detail: str = ""


@dataclass(frozen=True)
class Check:
    manifest_sha256: str
    files: int  # files the manifest lists
    problems: tuple[Problem, ...]

    @property
    def ok(self) -> bool:
        return not self.problems


def load(root: Path) -> tuple[dict[str, Any], bytes]:
    """The manifest (parsed) and its bytes; ValueError with a one-line reason when there is none or it is bad."""
    path = root / MANIFEST
    if not root.is_dir():
        raise ValueError(f"{root}: no such directory")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the manifest ({exc.strerror or exc})") from None
    try:
        doc = json.loads(raw)
    except ValueError:
        raise ValueError(f"{path}: not JSON") from None
    files = doc.get("files") if isinstance(doc, dict) else None
    if doc.get("format") != FORMAT or not isinstance(files, list) or not all(
            isinstance(f, dict) and isinstance(f.get("path"), str) and isinstance(f.get("sha256"), str)
            and isinstance(f.get("size"), int) for f in files):
        raise ValueError(f"{path}: not an isight-conformance manifest")
    return doc, raw


def check(root: Path) -> Check:
    """Recompute every file's hash and size; what differs from the manifest (ValueError: no usable manifest)."""
    doc, raw = load(root)
    digest = hashlib.sha256(raw).hexdigest()
    listed = {f["path"]: f for f in doc["files"]}
    present = set(package_files(root))
    problems: list[Problem] = []
    for rel in sorted(set(listed) | present):
        if rel not in present:
            problems.append(Problem("removed", rel))
        elif rel not in listed:
            problems.append(Problem("added", rel))
        else:
            sha, size = file_digest(root, rel)
            if (sha, size) != (listed[rel]["sha256"], listed[rel]["size"]):
                problems.append(Problem("changed", rel, f"{size} bytes, sha256 {sha}; manifest: "
                                                        f"{listed[rel]['size']} bytes, sha256 {listed[rel]['sha256']}"))
    report = root / REPORT
    if REPORT in present and REPORT in listed:
        found = SLOT.search(report.read_bytes())
        shown = found.group(1).decode() if found else ""
        if shown != digest:
            problems.append(Problem("report-field", REPORT, f"shows manifest sha256 {shown or '(none)'}; "
                                                            f"manifest.json is {digest}"))
    return Check(digest, len(listed), tuple(problems))
