"""The ``fuzz`` command: its help, its options and its handler (the campaign is :mod:`conformance.fuzz.launch`)."""

from __future__ import annotations

import argparse

from ..fuzz.database import DEFAULT_DATABASE
from ..fuzz.gating import add_gating_arguments
from ..fuzz.launch import main_fuzz
from ..i18n import N_, _
from .options import add_profile_group, add_target_options
from .registry import Command


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_target_options(p)
    p.add_argument("--stream-target", metavar="HOST:PORT", help=_("where the session machine's stream connection "
                   "goes (default: --target)"))
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--max-examples", type=int, metavar="N", help=_("fuzz cases to send (default: 5000)"))
    budget.add_argument("--duration", type=float, metavar="S", help=_("seconds to fuzz for"))
    add_gating_arguments(p, budget)
    p.add_argument("--seed", type=int, metavar="N", help=_("the campaign's seed (printed at the start; default: random)"))
    p.add_argument("--report-dir", metavar="DIR", help=_("fuzz-summary.json and one vector file per failure "
                   "(default: reports/fuzz-<timestamp>)"))
    p.add_argument("--pcap-dir", metavar="DIR", help=_("one pcapng per failure (default: pcaps/fuzz-<timestamp>)"))
    p.add_argument("--capture", choices=("failures", "all", "off"), default="failures",
                   help=_("pcaps of the failing examples (default), also every case of the campaign (all: "
                        "campaign-NNN.pcapng, about 0.8 KB per case), or none"))
    p.add_argument("--database", metavar="DIR|none|redis://HOST:PORT/DB",
                   help="hypothesis example database: failures found before are replayed first; a directory, none, "
                   f"or a redis URL shared by several machines (default: {DEFAULT_DATABASE}, or none when the active "
                   "hypothesis profile, e.g. its built-in 'ci' profile, switches the database off)")
    p.add_argument("--database-shared", metavar="URL|DIR",
                   help=_("also replay the failures saved in this store (a redis URL or a directory), read-only: "
                   "nothing is ever written to it (e.g. CI's corpus on a developer's machine)"))
    p.add_argument("--stateful-share", type=float, default=0.2, metavar="F",
                   help=_("share of the budget for the session state machine (default: 0.2; 0: frames only)"))
    p.add_argument("--categories", metavar="LIST", help=_("only these case categories, comma-separated "
                   "(e.g. B3-index,B4-floats; see docs/FUZZING.md)"))
    p.add_argument("--batch", type=int, default=32, metavar="N", help=_("most cases per hypothesis example (default: 32)"))
    p.add_argument("--liveness-every", type=int, default=64, metavar="K",
                   help=_("[R2] liveness check on a fresh connection every K cases, and after every anomaly (default: 64)"))
    p.add_argument("--max-failures", type=int, default=5, metavar="N", help=_("stop after N distinct failures (default: 5)"))
    p.add_argument("--restart-cmd", metavar="CMD",
                   help=_("[R2] a shell command that starts or brings back the box (e.g. './aibox --port 9004' or "
                   "'systemctl restart aibox'), run as this command's child: a death is confirmed, shrunk to the "
                   "shortest killing sequence, and the campaign goes on; what the box wrote before it died (a "
                   "sanitizer report, a traceback) is kept with the finding"))
    p.add_argument("--quiet", action="store_true", help=_("no progress lines"))
    add_profile_group(p, _("profile"))


COMMAND = Command(
    "fuzz", N_("fuzz an AI Box with hypothesis campaigns (valid and malformed frames, and a session state machine)"),
    add_arguments, main_fuzz,
    description=N_("Fuzz a box (or, with no --target, the bundled reference box): malformed and valid frames, each "
        "followed by a valid probe and judged by PROTOCOL.md (never 0000 to malformed input, A3's errors, answers in "
        "order, liveness on fresh connections), then a session state machine. Failures are shrunk and written as "
        "vector files (replay them with 'replay') and pcaps. Exit status: 0 no failure, 1 a failure found, 2 usage "
        "error or unreachable target. See docs/FUZZING.md."),
    lang=True,
)

