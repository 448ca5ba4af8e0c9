"""report.html: the self-contained report an integrator reads, prints and signs.

One file, no external reference (inline CSS and SVG; a few lines of optional inline
script for filtering, the page works without it). Jinja2 with autoescape on; every
string also passes :func:`~.summary.clean_text` (through the environment's
``finalize``), so whatever a box sent shows as visible escapes, never as markup.

Content, in order: the header to sign (run facts, profile with non-default settings
highlighted, overall line), the sign-off block, totals by verdict, the clause table
(every clause of PROTOCOL.md, untested ones marked), then every case in a
``<details>`` (non-PASS ones open).
"""

from __future__ import annotations

import functools
import json
import os
import re
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from urllib.parse import quote

import jinja2
from markupsafe import Markup

from ..options import PROFILE_OPTIONS
from ..protocol import DEFAULT_PROFILE
from ..suite.verdicts import VERDICT_ORDER, CaseResult, Level, SuiteInfo, Verdict, WireLine
from .summary import (
    CLAUSES,
    FAMILIES,
    atomic_write_bytes,
    by_clause,
    clean_text,
    format_duration,
    group_hex,
    hex_bytes,
    overall_line,
    overall_state,
    totals,
)
from .svg import histogram_svg, latency_svg

WIRE_HEAD, WIRE_TAIL = 150, 50  # wire lines shown per case: the first and the last ones
WIRE_HEX_BYTES = 48  # bytes of one wire line's hex shown in the table
HEX_DUMP_BYTES = 4096  # bytes of sent/received hex shown per case
DETAIL_CHARS = 2000  # characters of one details value shown

#: What each verdict means, for the reader who signs.
VERDICT_MEANING: dict[Verdict, str] = {
    Verdict.FAIL: "a MUST requirement is broken: the box does not conform",
    Verdict.ERROR: "the suite itself failed; the case says nothing about the box: rerun it",
    Verdict.NON_STRICT: "a SHOULD requirement is broken: allowed, but worth raising with the vendor",
    Verdict.INCONCLUSIVE: "could not be judged (box not ready, unreachable): neither pass nor fail",
    Verdict.INFORMATIONAL: "behaviour recorded where PROTOCOL.md allows a choice (MAY): never failing",
    Verdict.SKIP: "not applicable to this run (no UDP target, extension not implemented, deselected)",
    Verdict.PASS: "the requirement is met",
}

EXTENSION_MEANING = {
    "detected": "implemented (detected): E cases run",
    "not implemented": "not implemented (detected): E cases SKIP",
    "forced on": "forced on by the command line: E cases run",
    "on": "forced on by the command line: E cases run",
    "off": "switched off by the command line: E cases SKIP",
    "auto": "auto-detection requested",
}


# -- small presentation helpers --------------------------------------------------------
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


def display_time(iso: str) -> str:
    """``2026-05-09T07:35:25.123+00:00`` -> ``2026-05-09 07:35:25 UTC``; other text as given."""
    try:
        when = datetime.fromisoformat(iso.replace("Z", "+00:00"))
    except (ValueError, AttributeError):
        return iso
    if when.tzinfo is None:
        return when.strftime("%Y-%m-%d %H:%M:%S")
    return when.astimezone(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")


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


def profile_rows(profile: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per profile setting: flag, value, PROTOCOL.md default, changed?"""
    defaults = DEFAULT_PROFILE.to_dict()
    options = {o.field: o for o in PROFILE_OPTIONS}

    def shown(field: str, value: Any) -> str:
        value = getattr(value, "value", value)
        if field == "strict" and isinstance(value, bool):
            return "strict" if value else "lenient"
        return str(value)

    rows = []
    for name, value in profile.items():
        opt = options.get(name)
        known = name in defaults
        rows.append({
            "name": name,
            "flag": opt.flag if opt else "",
            "help": re.sub(r"^\[[^]]*\]\s*", "", opt.help) if opt else "",
            "clause": (re.match(r"^\[([^]]*)\]", opt.help) or [None, ""])[1] if opt else "",
            "value": shown(name, value),
            "default": shown(name, defaults[name]) if known else "(not a PROTOCOL.md setting)",
            "changed": not known or getattr(value, "value", value) != defaults[name],
        })
    return rows


def _detail_value(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value, ensure_ascii=False, default=str)
    return text if len(text) <= DETAIL_CHARS else text[:DETAIL_CHARS] + f"… ({len(text)} characters)"


def wire_rows(wire: Sequence[WireLine]) -> tuple[list[dict[str, str]], list[dict[str, str]], int]:
    """(first rows, last rows, number omitted between them)."""
    def row(w: WireLine) -> dict[str, str]:
        return {
            "t": f"{w.t_ms:.1f}", "conn": str(w.conn), "dir": w.direction,
            "cls": {"→": "sent", "←": "recv"}.get(w.direction, "event"),
            "kind": w.kind, "hex": group_hex(w.hex, per_line=0, limit=WIRE_HEX_BYTES) if w.hex else "",
            "summary": w.summary,
        }

    if len(wire) <= WIRE_HEAD + WIRE_TAIL:
        return [row(w) for w in wire], [], 0
    return ([row(w) for w in wire[:WIRE_HEAD]], [row(w) for w in wire[-WIRE_TAIL:]],
            len(wire) - WIRE_HEAD - WIRE_TAIL)


def case_view(case: CaseResult, anchor: str, suite: SuiteInfo, report_dir: Path,
              pcap_base: Path | None) -> dict[str, Any]:
    head, tail, omitted = wire_rows(case.wire)
    svg = None
    if case.latencies_ms:
        limit = case.details.get("time_out_ms", suite.profile.get("time_out_ms"))
        svg = Markup(latency_svg(case.latencies_ms, f"{case.id}: answer latency per request",
                                 time_out_ms=float(limit) if isinstance(limit, (int, float)) else None))
    histogram = _histogram(case)
    return {
        "id": case.id, "anchor": anchor, "title": case.title, "clauses": case.clauses,
        "level": case.level.value, "verdict": case.verdict.value, "cls": css_class(case.verdict),
        "open": case.verdict is not Verdict.PASS, "duration": format_duration(case.duration_s),
        "message": case.message, "requirement": case.requirement,
        "expected": case.expected, "observed": case.observed,
        "sent": hexdump(case.sent_hex) if case.sent_hex else "",
        "received": hexdump(case.received_hex) if case.received_hex else "",
        "wire_head": head, "wire_tail": tail, "wire_omitted": omitted, "wire_total": len(case.wire),
        "svg": svg, "histogram": histogram,
        "pcap": case.pcap, "pcap_href": pcap_href(case.pcap, report_dir, pcap_base) if case.pcap else None,
        "details": [(str(k), _detail_value(v)) for k, v in sorted(case.details.items(), key=lambda kv: str(kv[0]))
                    if not (k == HISTOGRAM_KEY and histogram is not None)],
    }


#: ``details[HISTOGRAM_KEY] = {"values_ms": [...], "bins": 40, "title": "...", "expected_ms": 20.0}``
#: is drawn as an interval histogram (certify-robot's T2 cases) instead of a details row.
HISTOGRAM_KEY = "interval_histogram"


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


# -- rendering -------------------------------------------------------------------------
def _finalize(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, str) and not isinstance(value, Markup):
        return clean_text(value)
    return value


@functools.cache
def environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("conformance.report", "templates"),
        autoescape=True, finalize=_finalize, trim_blocks=True, lstrip_blocks=True,
        undefined=jinja2.StrictUndefined,
    )
    env.filters["vclass"] = css_class
    return env


def render_html(suite: SuiteInfo, cases: list[CaseResult], report_dir: str | os.PathLike[str] = ".",
                pcap_base: Path | None = None) -> str:
    """The report as a string; pcap links are made relative to ``report_dir``."""
    report_dir = Path(report_dir)
    taken: set[str] = set()
    views = [case_view(c, anchor_of(c.id, taken), suite, report_dir, pcap_base) for c in cases]
    link: dict[str, tuple[str, str]] = {}  # case id -> (anchor, css class), for the clause table
    for v in views:
        link.setdefault(v["id"], (v["anchor"], v["cls"]))
    clause_results = by_clause(cases)
    families = []
    for letter, name in FAMILIES.items():
        rows = [r for c, r in clause_results.items() if c[:1] == letter]
        families.append({"letter": letter, "name": name, "rows": rows})
    extra = [r for c, r in clause_results.items() if c[:1] not in FAMILIES]
    if extra:
        families.append({"letter": "?", "name": "Other clause IDs named by cases", "rows": extra})
    t = totals(cases)
    untested = [c for c in CLAUSES if not clause_results[c].tested]
    profile = profile_rows(dict(suite.profile))
    return environment().get_template("report.html.j2").render(
        suite=suite, started=display_time(suite.started), duration=format_duration(suite.duration_s),
        extension=EXTENSION_MEANING.get(suite.extension, suite.extension),
        profile=profile, changed=[r for r in profile if r["changed"]],
        overall=overall_line(cases, suite), overall_state=overall_state(cases, suite),
        totals=t, total=len(cases), order=[v.value for v in VERDICT_ORDER],
        meaning={v.value: m for v, m in VERDICT_MEANING.items()},
        families=families, untested=untested, n_clauses=len(CLAUSES), link=link,
        levels=list(Level), cases=views, wire_head=WIRE_HEAD, wire_tail=WIRE_TAIL,
        generated=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"),
    )


def write_html(path: str | os.PathLike[str], suite: SuiteInfo, cases: list[CaseResult],
               pcap_base: Path | None = None) -> None:
    """Write report.html atomically. Relative ``case.pcap`` paths are taken relative to
    ``pcap_base`` (default: the current directory); links are relative to the report."""
    path = Path(path)
    html = render_html(suite, cases, path.parent, pcap_base)
    atomic_write_bytes(path, html.encode("utf-8", "replace"))
