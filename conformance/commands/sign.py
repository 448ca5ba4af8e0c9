"""``isight-conformance sign DIR --key KEY [--signer NAME] [--role ROLE]``: add one signature to a package.

OpenSSH signs the package's ``manifest.json`` (``ssh-keygen -Y sign``, namespace ``isight-conformance``);
the signature goes to ``DIR/signatures/<signer>.sig``. Several signers (vendor, integrator, witness) each add
theirs; ``verify --allowed-signers FILE`` checks them all. Exit status: 0 signed, 2 no manifest, no key,
ssh-keygen missing or refusing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..acceptance import manifest, signatures
from ..i18n import N_, _
from ..model.exit_codes import EXIT_OK, EXIT_USAGE
from .registry import Command


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("package", metavar="DIR", help=_("the report directory of a run (it holds manifest.json)"))
    p.add_argument("--key", metavar="KEY", required=True,
                   help=_("the signer's OpenSSH private key (ssh-keygen -Y sign -f KEY)"))
    p.add_argument("--signer", metavar="NAME", default=None,
                   help=_("the signer's principal as the receiver's allowed-signers file names it, e.g. "
                          "alice@vendor.example (default: the comment of KEY.pub)"))
    p.add_argument("--role", metavar="ROLE", default="",
                   help=_("the capacity the signer signs in: vendor, integrator, witness..."))


def main_sign(args: argparse.Namespace) -> int:
    root, key = Path(args.package), Path(args.key)
    signer = args.signer or signatures.key_comment(key)
    try:
        if not signer:
            raise ValueError(f"--signer: {key}.pub has no comment to name the signer; give --signer NAME")
        check = manifest.check(root)
        if not check.ok:
            raise ValueError(f"{root} does not match its manifest ({len(check.problems)} problem(s), first: "
                             f"{check.problems[0].kind} {check.problems[0].path}); run 'isight-conformance verify'")
        path = signatures.sign(root, key, signer, args.role)
    except ValueError as exc:
        print(f"isight-conformance sign: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print(_("signed manifest.json (sha256 {digest}) as {signer}: {path}").format(
        digest=check.manifest_sha256, signer=signer, path=path))
    return EXIT_OK


COMMAND = Command(
    "sign", N_("sign a report directory's manifest.json with an OpenSSH key (ssh-keygen -Y sign)"),
    add_arguments, main_sign,
    description=N_("Add one signature to a package (a run's --report-dir): OpenSSH signs its manifest.json, which "
        "lists every file with its SHA-256. The package must still match its manifest. Several signers may each "
        "add one; the receiver checks them with 'verify --allowed-signers FILE'."), lang=True,
)
