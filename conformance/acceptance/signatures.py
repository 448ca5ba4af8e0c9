"""Signatures of a package: OpenSSH's ``ssh-keygen -Y sign`` over ``manifest.json``, checked with ``-Y verify``.

No cryptography of our own: the signature is OpenSSH's SSHSIG format, made and checked by the ``ssh-keygen``
engineers already have (OpenSSH 8.1 or later), under the namespace :data:`NAMESPACE`. Each signer adds one file,
``signatures/<signer>.sig``, with ``signatures/<signer>.json`` beside it naming the signer (the principal the
allowed-signers file lists), the role they sign in (vendor, integrator, witness...) and the manifest hash they
signed. The manifest lists every other file, so one signature covers the package.
"""

from __future__ import annotations

import datetime as _dt
import json
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from ..report.summary import atomic_write_bytes
from .manifest import MANIFEST, SIGNATURES, load, sha256_of

NAMESPACE = "isight-conformance"
#: signing may wait for a passphrase typed at the terminal; verifying never waits for anyone
SIGN_TIMEOUT_S = 120.0
VERIFY_TIMEOUT_S = 20.0
_SAFE = re.compile(r"[^A-Za-z0-9@._+-]")


def ssh_keygen() -> str:
    """The path of ``ssh-keygen`` (ValueError when it is not installed)."""
    found = shutil.which("ssh-keygen")
    if found is None:
        raise ValueError("ssh-keygen not found: install OpenSSH (8.1 or later) to sign or check signatures")
    return found


def key_comment(key: Path) -> str:
    """The comment of ``KEY.pub`` (``user@host`` by default), or ""."""
    try:
        fields = key.with_name(key.name + ".pub").read_text(encoding="utf-8").split(None, 2)
    except (OSError, UnicodeDecodeError):
        return ""
    return fields[2].strip() if len(fields) == 3 else ""


def file_stem(signer: str) -> str:
    return _SAFE.sub("_", signer)[:80] or "signer"


def sign(root: Path, key: Path, signer: str, role: str = "") -> Path:
    """Sign the package's manifest with ``key`` as ``signer``; the signature file (written atomically)."""
    _doc, raw = load(root)
    if not key.is_file():
        raise ValueError(f"--key {key}: no such file")
    try:
        proc = subprocess.run([ssh_keygen(), "-Y", "sign", "-f", str(key), "-n", NAMESPACE, "-q"], input=raw,
                              capture_output=True, timeout=SIGN_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired:
        raise ValueError(f"ssh-keygen -Y sign did not finish within {SIGN_TIMEOUT_S:.0f} s") from None
    if proc.returncode != 0 or b"BEGIN SSH SIGNATURE" not in proc.stdout:
        why = proc.stderr.decode("utf-8", "replace").strip().splitlines()
        raise ValueError(f"ssh-keygen -Y sign failed: {why[-1] if why else f'exit status {proc.returncode}'}")
    folder = root / SIGNATURES
    stem = file_stem(signer)
    path = atomic_write_bytes(folder / f"{stem}.sig", proc.stdout)
    note = {"signer": signer, "role": role, "namespace": NAMESPACE, "signed_file": MANIFEST,
            "manifest_sha256": sha256_of(root / MANIFEST),
            "signed_at": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}
    atomic_write_bytes(folder / f"{stem}.json", (json.dumps(note, indent=1, ensure_ascii=False) + "\n").encode())
    return path


@dataclass(frozen=True)
class SignatureCheck:
    file: str  # signatures/<signer>.sig
    signer: str
    role: str
    good: bool
    detail: str  # ssh-keygen's own words


def signature_files(root: Path) -> list[Path]:
    folder = root / SIGNATURES
    return sorted(folder.glob("*.sig")) if folder.is_dir() else []


def _note(sig: Path) -> dict[str, str]:
    try:
        doc = json.loads(sig.with_suffix(".json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return {k: str(v) for k, v in doc.items()} if isinstance(doc, dict) else {}


def verify_all(root: Path, allowed_signers: Path) -> list[SignatureCheck]:
    """Check every signature of the package against ``allowed_signers`` (OpenSSH's format)."""
    if not allowed_signers.is_file():
        raise ValueError(f"--allowed-signers {allowed_signers}: no such file")
    _doc, raw = load(root)
    out = []
    for sig in signature_files(root):
        note = _note(sig)
        signer = note.get("signer", "")
        rel = sig.relative_to(root).as_posix()
        if not signer:
            out.append(SignatureCheck(rel, "", "", False, f"{sig.with_suffix('.json').name} missing or unreadable"))
            continue
        try:
            proc = subprocess.run([ssh_keygen(), "-Y", "verify", "-f", str(allowed_signers), "-I", signer,
                                   "-n", NAMESPACE, "-s", str(sig)], input=raw, capture_output=True,
                                  timeout=VERIFY_TIMEOUT_S, check=False)
        except subprocess.TimeoutExpired:
            out.append(SignatureCheck(rel, signer, note.get("role", ""), False, "ssh-keygen -Y verify timed out"))
            continue
        words = (proc.stdout + proc.stderr).decode("utf-8", "replace").strip().splitlines()
        out.append(SignatureCheck(rel, signer, note.get("role", ""), proc.returncode == 0,
                                  words[-1] if words else f"exit status {proc.returncode}"))
    return out
