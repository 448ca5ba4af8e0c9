"""The declared / observed table: each declaration of the vendor against what the run saw.

Each row is **confirmed** (with the case that showed it), **contradicted** (with the case, its bytes and its
pcap) or **not exercised** (nothing in this run could tell). Without a declaration the same table is filled with
what the run observed (PROFILE-01's inference and the rest), each row **inferred**.

A contradicted declaration is a finding of its own: :func:`findings` makes it a FAIL case, ``DECL-<key>``,
judged on the declaration's clause, so the run's overall line can never say CONFORMS over a declaration the box
contradicted.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from ..i18n import N_
from ..model.verdicts import CaseResult, Level, Verdict
from .declaration import ITEMS, Declaration, Item

CONFIRMED, CONTRADICTED, NOT_EXERCISED, INFERRED = "confirmed", "contradicted", "not exercised", "inferred"
GOOD = (Verdict.PASS, Verdict.INFORMATIONAL)


@dataclass(frozen=True)
class Seen:
    """What the run observed of one choice: a value (None: nothing told), the case that showed it, and which
    declared values agree with it (``accepts``). Words (values and notes) are N_()-marked English: summary.json
    keeps them so, report.html shows them translated."""

    value: str | None
    case: CaseResult | None = None
    accepts: Callable[[Any], bool] | None = None
    note: str = ""


def _case(cases: Sequence[CaseResult], prefix: str) -> list[CaseResult]:
    return [c for c in cases if c.id == prefix or c.id.startswith(prefix + "[") or c.id.startswith(prefix + "-")]


def _first(cases: Sequence[CaseResult], *prefixes: str) -> CaseResult | None:
    for prefix in prefixes:
        found = _case(cases, prefix)
        if found:
            return found[0]
    return None


def _discovered(cases: Sequence[CaseResult], key: str) -> Seen | None:
    p01 = _first(cases, "PROFILE-01")
    found = (p01.details.get("discovered") or {}) if p01 is not None else {}
    if p01 is None or key not in found:
        return None
    value = found[key]
    return Seen(str(value), p01, lambda d: str(d) == str(value))


def _by_verdict(cases: Sequence[CaseResult], prefix: str, good: str, bad: str,
                good_accepts: Callable[[Any], bool], bad_accepts: Callable[[Any], bool], clause: str = "") -> Seen:
    """The first judged case of ``prefix``: a pass says ``good``; a FAIL or NON-STRICT says ``bad`` when it
    judged ``clause`` (a verdict on another clause of the case, say T1's time-out, tells nothing of it)."""
    for case in _case(cases, prefix):
        if case.verdict in GOOD:
            return Seen(good, case, good_accepts)
        if case.verdict in (Verdict.FAIL, Verdict.NON_STRICT):
            if clause and case.judged and clause not in case.judged:
                continue
            return Seen(bad, case, bad_accepts)
    return Seen(None)


def _profile_choice(key: str, cases: Sequence[CaseResult]) -> Seen:
    """first_index, byte_order, crc, crc_byte_order: PROFILE-01's discovery, else the case judging it."""
    found = _discovered(cases, key)
    if found is not None:
        return found
    if key == "first_index":
        b301 = _first(cases, "B3-01")
        accepted = (b301.details.get("first_index") or {}).get("accepted") if b301 is not None else None
        if isinstance(accepted, (list, tuple)) and accepted:
            return Seen(" or ".join(map(str, accepted)), b301, lambda d: d in accepted)
        return Seen(None)
    if key == "byte_order":
        return _by_verdict(cases, "F4-01", N_("as the profile reads it"), N_("the other byte order"),
                           lambda d: True, lambda d: False, "F4")
    return _by_verdict(cases, "F7-01", N_("as the profile reads it"), N_("not as the profile reads it"),
                       lambda d: True, lambda d: False, "F7")


def _extension(cases: Sequence[CaseResult], suite: dict[str, Any]) -> Seen:
    """extension_e: what the session's detection found (an E case named as the one that showed it)."""
    how = str(suite.get("extension", ""))
    e_case = next((c for c in cases if c.id.startswith("E")), None) or next(
        (c for c in cases if any(cl.startswith("E") for cl in c.clauses)), None)
    if how.startswith("not implemented"):
        return Seen("false", e_case, lambda d: d is False)
    if how == "detected" or how.startswith("implemented"):
        return Seen("true", e_case, lambda d: d is True)
    return Seen(None, note=how)


def _r6_framing(cases: Sequence[CaseResult]) -> Seen:
    """r6_framing: every legal framing passes R6-01 alike; only a box that hangs silently contradicts one."""
    seen = _by_verdict(cases, "R6-01", N_("resynchronises or closes (a legal framing)"),
                       N_("hangs silently after garbage"), lambda d: True, lambda d: False, "R6")
    if seen.value is not None and seen.accepts is not None and seen.accepts(None):
        return Seen(None, seen.case, note=N_("every legal framing passes R6-01 alike"))
    return seen


def _latency(cases: Sequence[CaseResult]) -> Seen:
    """answer_latency_ms: the longest answer latency of the cases that time answers (T1)."""
    timed = [(max(c.latencies_ms), c) for c in cases if c.latencies_ms and "T1" in c.clauses]
    if not timed:
        return Seen(None)
    worst, case = max(timed, key=lambda t: t[0])
    return Seen(f"≤ {worst:.1f} ms", case, lambda d: worst <= d)


def observe(item: Item, cases: Sequence[CaseResult], suite: dict[str, Any]) -> Seen:
    """What the run saw of ``item``'s choice (float_byte_order: nothing, no answer tells it)."""
    key = item.key
    if key in ("first_index", "byte_order", "crc", "crc_byte_order"):
        return _profile_choice(key, cases)
    if key == "tcp_check":
        return _by_verdict(cases, "F6-02", N_("00 00 or a correct CRC"), N_("only 00 00"),
                           lambda d: d != "zero", lambda d: d == "zero", "F6")
    if key == "extension_e":
        return _extension(cases, suite)
    if key == "progidx_conflict":
        return _by_verdict(cases, "E2-01", N_("as the profile reads it"), N_("not as the profile reads it"),
                           lambda d: True, lambda d: False, "E2")
    if key == "cycle_state":
        return Seen(None, note=N_("S3: a tester must not depend on either; the suite never tells them apart"))
    if key == "r6_framing":
        return _r6_framing(cases)
    if key == "connections":
        return _by_verdict(cases, "S4-01", N_("2 or more at once"), N_("1 at a time"),
                           lambda d: d >= 2, lambda d: d == 1, "S4")
    if key == "answer_latency_ms":
        return _latency(cases)
    return Seen(None)


#: wire lines a contradicted row quotes when its case names no bytes of its own
EVIDENCE_LINES = 6


def evidence(case: CaseResult, key: str) -> tuple[str, str, str]:
    """(what the case saw of ``key`` with its bytes, sent hex, received hex) for a contradicted row: the case's
    own sent/received bytes, else the first lines of its wire log that carry bytes."""
    seen = case.details.get(key)
    text = "; ".join(f"{k}: {v}" for k, v in seen.items()) if isinstance(seen, dict) else str(seen or "")
    sent, received = case.sent_hex, case.received_hex
    if not sent and not received:
        lines = [w for w in case.wire if w.hex][:EVIDENCE_LINES]
        sent = " | ".join(w.hex for w in lines if w.direction == "→")
        received = " | ".join(w.hex for w in lines if w.direction == "←")
        quoted = "; ".join(f"{w.direction} {w.hex}" for w in lines)
    else:
        quoted = "; ".join(f"{arrow} {h}" for arrow, h in (("→", sent), ("←", received)) if h)
    return " · ".join(p for p in (text, quoted) if p)[:900], sent, received


def _shown(value: Any) -> str:
    return ("true" if value else "false") if isinstance(value, bool) else str(value)


def table(declaration: Declaration | None, cases: Sequence[CaseResult], suite: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per declared item (or, without a declaration, per item the run observed)."""
    rows = []
    for item in ITEMS:
        seen = observe(item, cases, suite)
        case = seen.case
        row: dict[str, Any] = {"key": item.key, "clause": item.clause, "label": item.label,
                               "declared": None, "observed": seen.value, "note": seen.note,
                               "case": case.id if case is not None else None, "bytes": "",
                               "pcap": case.pcap if case is not None else None,
                               "sent_hex": "", "received_hex": ""}
        if declaration is None:
            if seen.value is None:
                continue
            row["status"] = INFERRED
        elif item.key not in declaration.values:
            continue
        else:
            declared = declaration.values[item.key]
            row["declared"] = _shown(declared)
            if seen.value is None or seen.accepts is None:
                row["status"] = NOT_EXERCISED
            elif seen.accepts(declared):
                row["status"] = CONFIRMED
            else:
                row["status"] = CONTRADICTED
                if case is not None:
                    row["bytes"], row["sent_hex"], row["received_hex"] = evidence(case, item.key)
        rows.append(row)
    return rows


def findings(rows: Sequence[dict[str, Any]]) -> list[CaseResult]:
    """A FAIL case per contradicted declaration (``DECL-<key>``), judged on its clause."""
    out = []
    for row in rows:
        if row["status"] != CONTRADICTED:
            continue
        clause = row["clause"]
        evidence = f"; shown by {row['case']}" if row["case"] else ""
        out.append(CaseResult(
            id=f"DECL-{row['key']}", title=f"The vendor's declaration holds: {row['key']} = {row['declared']}",
            clauses=(clause,), level=Level.MUST, verdict=Verdict.FAIL,
            message=f"{clause}: declared {row['key']} = {row['declared']}, observed {row['observed']}{evidence}",
            requirement=f"{clause}: the box behaves as its vendor declared ({row['key']} = {row['declared']})",
            expected=str(row["declared"]), observed=str(row["observed"]), pcap=row["pcap"],
            sent_hex=row["sent_hex"], received_hex=row["received_hex"],
            details={"declaration": row["key"], "case": row["case"] or "", "bytes": row["bytes"]},
            judged=(clause,)))
    return out
