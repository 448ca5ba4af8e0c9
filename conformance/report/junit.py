"""junit.xml for CI systems (Jenkins, GitLab, Azure DevOps...).

Layout as pytest writes it: ``<testsuites>`` holding one ``<testsuite
name="isight-conformance">`` with a ``<properties>`` block (target, profile settings,
version) and one ``<testcase>`` per case, named ``"<case id> <title>"`` with class
``isight.<family of its first clause>`` so CI groups the cases by clause family.

Verdict mapping (CI tools know only pass/fail/error/skip):

=============  =====================================================================
FAIL           ``<failure type="FAIL">``, body: requirement, expected, observed, hex
ERROR          ``<error type="ERROR">`` (the suite's own fault), same body
SKIP           ``<skipped>``
INCONCLUSIVE   ``<skipped message="INCONCLUSIVE: ...">`` (could not be judged)
NON-STRICT     passes; ``<system-out>`` holds the message and what was seen
INFORMATIONAL  passes; ``<system-out>`` likewise
=============  =====================================================================

Every testcase also carries ``<properties>`` with its verdict, level and clauses.
All text goes through :func:`~.summary.clean_text` (control characters become visible
escapes) so the file is valid XML 1.0 whatever bytes a box sent.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from datetime import datetime, timezone
from typing import Any

from ..suite.verdicts import CaseResult, SuiteInfo, Verdict
from .summary import atomic_write_bytes, clean_text, family_of, group_hex, one_line, totals

SUITE_NAME = "isight-conformance"
HEX_LIMIT = 4096  # bytes of sent/received hex quoted in a failure body
DETAIL_LIMIT = 4000  # characters of one details value quoted in a body


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attrs: Any) -> ET.Element:
    el = ET.SubElement(parent, tag, {k: clean_text(v) for k, v in attrs.items()})
    if text is not None:
        el.text = clean_text(text)
    return el


def junit_timestamp(started: str) -> str:
    """ISO 8601 as the JUnit schema wants it: ``YYYY-MM-DDThh:mm:ss`` (UTC, no zone)."""
    try:
        when = datetime.fromisoformat(started.replace("Z", "+00:00"))
    except (ValueError, AttributeError):
        return clean_text(started)
    if when.tzinfo is not None:
        when = when.astimezone(timezone.utc).replace(tzinfo=None)
    return when.replace(microsecond=0).isoformat()


def case_body(case: CaseResult) -> str:
    """The evidence of one case as plain text (failure/error body, system-out)."""
    lines = [f"verdict: {case.verdict.value}  level: {case.level.value}  clauses: {', '.join(case.clauses)}"]
    for label, value in (("message", case.message), ("requirement", case.requirement),
                         ("expected", case.expected), ("observed", case.observed)):
        if value:
            lines.append(f"{label}: {value}")
    for label, value in (("sent", case.sent_hex), ("received", case.received_hex)):
        if value:
            lines.append(f"{label} (hex):")
            lines.extend("  " + row for row in group_hex(value, limit=HEX_LIMIT).splitlines())
    if case.pcap:
        lines.append(f"pcap: {case.pcap}")
    for key, value in sorted(case.details.items(), key=lambda kv: str(kv[0])):
        text = str(value)
        if len(text) > DETAIL_LIMIT:
            text = text[:DETAIL_LIMIT] + f"… ({len(text)} characters)"
        lines.append(f"{key}: {text}")
    return "\n".join(lines)


def _fmt_time(seconds: float) -> str:
    return f"{max(0.0, seconds):.3f}"


def build_junit(suite: SuiteInfo, cases: list[CaseResult]) -> ET.Element:
    """The JUnit document as an ElementTree element (``<testsuites>``)."""
    t = totals(cases)
    counts = {
        "tests": str(len(cases)),
        "failures": str(t[Verdict.FAIL.value]),
        "errors": str(t[Verdict.ERROR.value]),
        "skipped": str(t[Verdict.SKIP.value] + t[Verdict.INCONCLUSIVE.value]),
        "time": _fmt_time(suite.duration_s),
    }
    root = ET.Element("testsuites", {"name": SUITE_NAME, **counts})
    ts = _sub(root, "testsuite", name=SUITE_NAME, **counts, timestamp=junit_timestamp(suite.started))

    props = _sub(ts, "properties")
    suite_props: list[tuple[str, Any]] = [
        ("version", suite.version), ("started", suite.started), ("target", suite.target),
        ("udp_target", suite.udp_target or "none"), ("extension", suite.extension),
        ("expected_failures", suite.expected_failures or "none"), ("command", suite.command),
    ]
    suite_props += [(f"profile.{k}", getattr(v, "value", v)) for k, v in suite.profile.items()]
    suite_props += [(f"totals.{k}", n) for k, n in t.items()]
    for name, value in suite_props:
        _sub(props, "property", name=name, value=value)

    for case in cases:
        tc = _sub(ts, "testcase", name=one_line(f"{case.id} {case.title}", 300),
                  classname=f"isight.{family_of(case)}", time=_fmt_time(case.duration_s))
        cprops = _sub(tc, "properties")
        for name, value in (("verdict", case.verdict.value), ("level", case.level.value),
                            ("clauses", " ".join(case.clauses))):
            _sub(cprops, "property", name=name, value=value)
        message = one_line(case.message or case.verdict.value)
        v = case.verdict
        if v is Verdict.FAIL:
            _sub(tc, "failure", case_body(case), message=message, type="FAIL")
        elif v is Verdict.ERROR:
            _sub(tc, "error", case_body(case), message=message, type="ERROR")
        elif v is Verdict.SKIP:
            _sub(tc, "skipped", message=message)
        elif v is Verdict.INCONCLUSIVE:
            _sub(tc, "skipped", message=one_line(f"INCONCLUSIVE (could not be judged): {case.message}"))
        if v in (Verdict.NON_STRICT, Verdict.INFORMATIONAL, Verdict.INCONCLUSIVE):
            _sub(tc, "system-out", case_body(case))
    return root


def junit_bytes(suite: SuiteInfo, cases: list[CaseResult]) -> bytes:
    root = build_junit(suite, cases)
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def write_junit(path: str | os.PathLike[str], suite: SuiteInfo, cases: list[CaseResult]) -> None:
    """Write junit.xml atomically."""
    atomic_write_bytes(path, junit_bytes(suite, cases))
