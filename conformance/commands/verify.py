"""``isight-conformance verify DIR [--allowed-signers FILE]``: is this package what was written?

Recomputes the SHA-256 and size of every file of the package and compares them with its ``manifest.json``
(:mod:`conformance.acceptance.manifest`); with ``--allowed-signers``, checks every signature with OpenSSH
(:mod:`conformance.acceptance.signatures`). Exit status: 0 OK, 1 a file changed, added or removed, a bad
signature, or (with ``--allowed-signers``) none at all; 2 no such directory, no manifest, no such file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..acceptance import manifest, signatures
from ..i18n import N_, _
from ..model.exit_codes import EXIT_FAILED, EXIT_OK, EXIT_USAGE
from .registry import Command

KIND_WORDS = {
    "changed": N_("CHANGED"),
    "added": N_("ADDED"),
    "removed": N_("REMOVED"),
    "report-field": N_("REPORT HASH"),
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("package", metavar="DIR", help=_("the report directory of a run (it holds manifest.json)"))
    p.add_argument("--allowed-signers", metavar="FILE", default=None,
                   help=_("OpenSSH allowed-signers file: check every signature of the package against it "
                          "(ssh-keygen -Y verify); without it signatures are only counted"))


def main_verify(args: argparse.Namespace) -> int:
    root = Path(args.package)
    try:
        found = manifest.check(root)
        checked = (signatures.verify_all(root, Path(args.allowed_signers))
                   if args.allowed_signers else None)
    except ValueError as exc:
        print(f"isight-conformance verify: {exc}", file=sys.stderr)
        return EXIT_USAGE
    for problem in found.problems:
        line = f"{_(KIND_WORDS[problem.kind])}: {problem.path}"
        print(line + (f" ({problem.detail})" if problem.detail else ""))
    bad_signature = False
    if checked is None:
        n = len(signatures.signature_files(root))
        if n:
            print(_("{n} signature(s) not checked: give --allowed-signers FILE").format(n=n))
    else:
        for sig in checked:
            word = _("GOOD SIGNATURE") if sig.good else _("BAD SIGNATURE")
            role = f" ({sig.role})" if sig.role else ""
            print(f"{word}: {sig.signer or '?'}{role} [{sig.file}]: {sig.detail}")
        if not checked:
            print(_("BAD SIGNATURE: the package has no signature"))
        bad_signature = not checked or not all(s.good for s in checked)
    if found.ok and not bad_signature:
        print(_("OK: {n} files match manifest.json (sha256 {digest})").format(n=found.files, digest=found.manifest_sha256))
        return EXIT_OK
    print(_("NOT OK: {n} file problem(s), signatures {sig}").format(
        n=len(found.problems), sig=_("bad") if bad_signature else _("good") if checked else _("not checked")))
    return EXIT_FAILED


COMMAND = Command(
    "verify", N_("check a report directory against its manifest.json (and its signatures): OK, or each file "
                 "changed, added or removed"), add_arguments, main_verify,
    description=N_("Recompute the SHA-256 and size of every file of a package (a run's --report-dir) and compare "
        "them with its manifest.json; with --allowed-signers, check every signature (ssh-keygen -Y verify). "
        "Exit status: 0 OK, 1 a file changed, added or removed, or a signature bad or missing, 2 no such "
        "directory or no manifest."), lang=True,
)
