"""The view of one case in report.html: what its ``<details>`` shows on screen and on paper.

On screen every case keeps its full evidence one click away (wire log, plots, hex dumps,
details). On paper (``@media print``) only the *print cards* show a body, and a bounded
one: the FAIL, ERROR, NON-STRICT and INCONCLUSIVE cases that no root cause explains, the
first case a root cause explains (its worked example), and of several cases with the same
finding (verdict and requirement) the first. Every other case prints as one line.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from urllib.parse import quote

from markupsafe import Markup

from ..model.verdicts import CaseResult, SuiteInfo, Verdict, WireLine
from .clausetext import judged_texts
from .summary import clean_text, format_duration, group_hex, hex_bytes
from .svg import histogram_svg, latency_svg

WIRE_HEAD, WIRE_TAIL = 150, 50  # wire lines shown per case: the first and the last ones
WIRE_PRINT_HEAD, WIRE_PRINT_TAIL = 5, 2  # of those, the ones a print card shows
WIRE_HEX_BYTES = 48  # bytes of one wire line's hex shown in the table
HEX_DUMP_BYTES = 4096  # bytes of sent/received hex shown per case
HEX_PRINT_ROWS = 2  # rows of 16 bytes a print card shows
DETAIL_CHARS = 2000  # characters of one details value shown
PRINT_CARDS = 40  # at most this many cases print their body; the rest print as one line
#: verdicts whose cases print a card (INFORMATIONAL, SKIP and PASS print one line)
CARD_VERDICTS = (Verdict.FAIL, Verdict.ERROR, Verdict.NON_STRICT, Verdict.INCONCLUSIVE)

#: ``details[HISTOGRAM_KEY] = {"values_ms": [...], "bins": 40, "title": "...", "expected_ms": 20.0}``
#: is drawn as an interval histogram (certify-robot's T2 cases) instead of a details row.
HISTOGRAM_KEY = "interval_histogram"


def css_class(verdict: Verdict | str | None) -> str:
    """``v-FAIL``, ``v-NON-STRICT`` ... or ``v-none`` for a clause not tested."""
    return "v-none" if verdict is None else f"v-{Verdict(verdict).value}"


def anchor_of(case_id: str, taken: set[str]) -> str:
    base = "case-" + re.sub(r"[^A-Za-z0-9_-]", "_", case_id)
    anchor, n = base, 2
    while anchor in taken:
        anchor, n = f"{base}-{n}", n + 1
    taken.add(anchor)
    return anchor


def hexdump(text: str, limit: int = HEX_DUMP_BYTES) -> str:
    """Hex as an offset-prefixed dump, 16 bytes a line in two groups of 8."""
    octets = hex_bytes(text)
    if octets is None:  # not hex: show the text as it is
        return clean_text(text)
    rows = []
    for off in range(0, min(len(octets), limit), 16):
        chunk = octets[off : off + 16]
        rows.append(f"{off:04x}  {' '.join(chunk[:8])}{'  ' if len(chunk) > 8 else ''}{' '.join(chunk[8:])}")
    if len(octets) > limit:
        rows.append(f"… {len(octets)} bytes in all; the first {limit} shown (all of them are in the pcap)")
    return "\n".join(rows)


def _hex_view(text: str) -> dict[str, Any]:
    """A hexdump split where a print card cuts it: ``head`` prints, ``rest`` is screen only."""
    rows = hexdump(text).split("\n") if text else []
    octets = hex_bytes(text) if text else None
    return {"head": "\n".join(rows[:HEX_PRINT_ROWS]), "rest": "\n".join(rows[HEX_PRINT_ROWS:]),
            "bytes": len(octets) if octets is not None else None}


def pcap_href(pcap: str, report_dir: Path, pcap_base: Path | None) -> str:
    """The pcap as a link relative to the report's directory.

    A relative ``pcap`` is taken relative to ``pcap_base`` (default: the current
    directory). The result is percent-encoded, so no path can become a URL scheme.
    """
    p = Path(pcap)
    if not p.is_absolute():
        p = (pcap_base or Path.cwd()) / p
    rel = os.path.relpath(os.path.abspath(p), os.path.abspath(report_dir))
    return quote(Path(rel).as_posix(), safe="/")


def _detail_value(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value, ensure_ascii=False, default=str)
    return text if len(text) <= DETAIL_CHARS else text[:DETAIL_CHARS] + f"… ({len(text)} characters)"


def wire_rows(wire: Sequence[WireLine]) -> tuple[list[dict[str, Any]], list[dict[str, Any]], int]:
    """(first rows, last rows, number omitted between them). A row a print card leaves
    out has ``extra`` set."""
    def row(w: WireLine, extra: bool) -> dict[str, Any]:
        return {
            "t": f"{w.t_ms:.1f}", "conn": str(w.conn), "dir": w.direction,
            "cls": {"→": "sent", "←": "recv"}.get(w.direction, "event") + (" pextra" if extra else ""),
            "kind": w.kind, "hex": group_hex(w.hex, per_line=0, limit=WIRE_HEX_BYTES) if w.hex else "",
            "summary": w.summary,
        }

    n = len(wire)
    if n <= WIRE_HEAD + WIRE_TAIL:
        cut = n > WIRE_PRINT_HEAD + WIRE_PRINT_TAIL + 1  # never cut a single line
        return [row(w, cut and WIRE_PRINT_HEAD <= i < n - WIRE_PRINT_TAIL) for i, w in enumerate(wire)], [], 0
    return ([row(w, i >= WIRE_PRINT_HEAD) for i, w in enumerate(wire[:WIRE_HEAD])],
            [row(w, i < WIRE_TAIL - WIRE_PRINT_TAIL) for i, w in enumerate(wire[-WIRE_TAIL:])],
            n - WIRE_HEAD - WIRE_TAIL)


def _histogram(case: CaseResult) -> Markup | None:
    spec = case.details.get(HISTOGRAM_KEY)
    if not isinstance(spec, dict) or not isinstance(spec.get("values_ms"), (list, tuple)):
        return None
    try:
        values = [float(v) for v in spec["values_ms"]]
        expected = spec.get("expected_ms")
        return Markup(histogram_svg(values, int(spec.get("bins", 40)), str(spec.get("title") or f"{case.id}: intervals"),
                                    float(expected) if isinstance(expected, (int, float)) else None))
    except (TypeError, ValueError, OverflowError):
        return None


_NUMBERISH = re.compile(r"[0-9A-Fa-f]*[0-9][0-9A-Fa-f]*")


def finding_key(case: CaseResult) -> tuple[str, str]:
    """Cases with the same key show the same finding: verdict and requirement (or the
    message up to its first ": expected"), numbers and hex words aside ("vector tc27"
    and "vector tc28" are one finding)."""
    what = case.requirement or case.message.split(": expected", 1)[0]
    return case.verdict.value, _NUMBERISH.sub("#", " ".join(what.split())[:200])


def print_cards(cases: Sequence[CaseResult]) -> set[int]:
    """The indexes of the cases that print their body (see the module docstring)."""
    cards: set[int] = set()
    seen_causes: set[str] = set()
    seen_findings: set[tuple[str, str]] = set()
    for i, case in enumerate(cases):
        if case.verdict not in CARD_VERDICTS:
            continue
        if case.root_cause:
            if case.root_cause in seen_causes:
                continue
            seen_causes.add(case.root_cause)
        else:
            key = finding_key(case)
            if key in seen_findings:
                continue
            seen_findings.add(key)
        cards.add(i)
        if len(cards) >= PRINT_CARDS:
            break
    return cards


def case_view(case: CaseResult, anchor: str, suite: SuiteInfo, report_dir: Path,
              pcap_base: Path | None, card: bool = False) -> dict[str, Any]:
    head, tail, omitted = wire_rows(case.wire)
    svg = None
    if case.latencies_ms:
        limit = case.details.get("time_out_ms", suite.profile.get("time_out_ms"))
        svg = Markup(latency_svg(case.latencies_ms, f"{case.id}: answer latency per request",
                                 time_out_ms=float(limit) if isinstance(limit, (int, float)) else None))
    histogram = _histogram(case)
    passed = case.verdict is Verdict.PASS
    return {
        "id": case.id, "anchor": anchor, "title": case.title, "clauses": case.clauses,
        "level": case.level.value, "verdict": case.verdict.value, "cls": css_class(case.verdict),
        # on screen, a case a root cause explains opens with one click (the first one is open)
        "open": not passed and (not case.root_cause or card), "card": card,
        "finding": case.verdict in CARD_VERDICTS,  # listed under Findings
        "duration": format_duration(case.duration_s),
        "message": case.message, "requirement": case.requirement,
        "expected": case.expected, "observed": case.observed,
        "clause_texts": [] if passed else judged_texts(case), "root_cause": case.root_cause,
        "sent": _hex_view(case.sent_hex), "received": _hex_view(case.received_hex),
        "wire_head": head, "wire_tail": tail, "wire_omitted": omitted, "wire_total": len(case.wire),
        "wire_print_omitted": (len(case.wire) - WIRE_PRINT_HEAD - WIRE_PRINT_TAIL
                               if len(case.wire) > WIRE_PRINT_HEAD + WIRE_PRINT_TAIL + 1 else 0),
        "svg": svg, "histogram": histogram,
        "pcap": case.pcap, "pcap_href": pcap_href(case.pcap, report_dir, pcap_base) if case.pcap else None,
        "details": [(str(k), _detail_value(v)) for k, v in sorted(case.details.items(), key=lambda kv: str(kv[0]))
                    if not (k == HISTOGRAM_KEY and histogram is not None)],
    }
