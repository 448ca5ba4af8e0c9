"""Root causes of the transport: UDP datagrams (F7, R7) and the TCP check field (F6).

A box that reads UDP another way (another CRC, no CRC check, a CRC over part of the frame,
several frames per datagram, answers sent to another port) or writes something other than
00 00 in the TCP check field fails a handful of cases, often one each, with signatures no
group shares. :func:`transport_causes` gathers them, so that no such FAIL stands alone:

* ``udp``: every judged case of the UDP family (F7-*, R7-*), and a FUZZ case whose failing
  example was a datagram;
* ``tcp-check``: every judged case of F6.

Their titles say only what failed; the diagnose phase's UDP family
(:mod:`conformance.diagnose.udp_family`) names the mechanism.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..i18n import gettext
from ..model.verdicts import CaseResult, RootCause, Verdict
from .patterns import Claim, evidence_of

#: the root-cause kinds this module makes
UDP, TCP_CHECK = "udp", "tcp-check"
_JUDGED = (Verdict.FAIL, Verdict.NON_STRICT)
_UDP_FAMILY = ("F7-", "R7-")


def udp_fuzz(case: CaseResult) -> bool:
    """A fuzz case whose first failing example went over UDP."""
    failures = (case.details.get("fuzz") or {}).get("failures") or []
    first = failures[0] if failures and isinstance(failures[0], dict) else {}
    examples = first.get("cases") or [{}]
    return bool(examples) and isinstance(examples[0], dict) and examples[0].get("transport") == "udp"


def _clauses(members: list[CaseResult], first: tuple[str, ...]) -> tuple[str, ...]:
    named = [c for m in members for c in (m.judged or m.clauses)]
    return tuple(dict.fromkeys([*first, *(c for c in named if c in ("F7", "R7", "F6", "A1", "T1"))]))[:3]


def transport_causes(cases: Sequence[CaseResult]) -> list[Claim]:
    out: list[Claim] = []
    udp = [c for c in cases if c.verdict in _JUDGED and (c.id.startswith(_UDP_FAMILY) or udp_fuzz(c))]
    if udp:
        ids = ", ".join(c.id for c in udp[:4]) + (", …" if len(udp) > 4 else "")
        title = gettext("The box does not handle UDP datagrams as F7/R7 ask: {n} case(s) fail ({ids})").format(
            n=len(udp), ids=ids)
        out.append((RootCause("", _clauses(udp, ("F7",)), title, evidence_of(udp[0]), kind=UDP), udp))
    check = [c for c in cases if c.verdict in _JUDGED and c.id.startswith("F6-")]
    if check:
        title = gettext("The box's TCP check field is not what F6 asks: {n} case(s) fail ({ids})").format(
            n=len(check), ids=", ".join(c.id for c in check))
        out.append((RootCause("", ("F6",), title, evidence_of(check[0]), kind=TCP_CHECK), check))
    return out
