"""junit.xml for CI systems (Jenkins, GitLab, Azure DevOps...).

The file validates against Jenkins' ``junit-10.xsd`` (a copy is in ``tests/``). Layout
as pytest writes it: ``<testsuites>`` holding one ``<testsuite name="isight-conformance">``
with a ``<properties>`` block (target, profile settings, versions, root causes), one
``<testcase>`` per case and a suite ``<system-out>`` with the overall line. A testcase is
named ``"<case id> <title>"`` (stable from run to run, so CI keeps each case's history)
with class ``isight.<family of its first clause>`` so CI groups cases by clause family.

Verdict mapping (CI tools know only pass/fail/error/skip):

=============  =====================================================================
FAIL           ``<failure type="FAIL">``, body: requirement, clause text, expected, observed, hex
ERROR          ``<error type="ERROR">`` (the suite's own fault), same body
SKIP           ``<skipped>``
INCONCLUSIVE   ``<skipped message="INCONCLUSIVE: ...">`` (could not be judged)
NON-STRICT     passes; ``<system-out>`` starts ``NON-STRICT:`` with the message
INFORMATIONAL  passes; ``<system-out>`` starts ``INFORMATIONAL:``
=============  =====================================================================

Every testcase has a ``<system-out>`` whose first line is the verdict word and the
message, followed by the case's level, clauses (with the text of the judged ones), root
cause and pcap: the schema allows no ``<properties>`` inside a testcase. The suite's
``<system-out>`` and its ``nonstrict`` property list the NON-STRICT cases, so they stay
visible in CI although they pass. All text goes through :func:`~.summary.clean_text`
(control characters become visible escapes) so the file is valid XML 1.0 whatever bytes
a box sent.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from datetime import datetime, timezone
from typing import Any

from .. import i18n
from ..i18n import N_, _
from ..model.verdicts import CaseResult, RootCause, SuiteInfo, Verdict
from .clausetext import judged_texts
from .summary import (
    atomic_write_bytes,
    clean_text,
    family_of,
    group_hex,
    one_line,
    overall_line,
    suite_dict,
    totals,
)

SUITE_NAME = "isight-conformance"
HEX_LIMIT = 4096  # bytes of sent/received hex quoted in a failure body
DETAIL_LIMIT = 4000  # characters of one details value quoted in a body
LIST_LIMIT = 50  # case ids listed in one suite property

#: the first word of a testcase's system-out, and why a passing case carries it
OUT_NOTE: dict[Verdict, str] = {
    Verdict.NON_STRICT: N_("a SHOULD is broken; the case passes in CI"),
    Verdict.INFORMATIONAL: N_("recorded behaviour (MAY); never failing"),
    Verdict.INCONCLUSIVE: N_("could not be judged; reported as skipped"),
}


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


def case_meta(case: CaseResult, root_causes: dict[str, RootCause] | None = None) -> list[str]:
    """The first lines of a case's text: verdict word and message, level, clauses (with
    the text of the judged ones), root cause, pcap."""
    head = f"{case.verdict.value}: {one_line(case.message)}" if case.message else case.verdict.value
    if case.verdict in OUT_NOTE:
        head += f"  ({_(OUT_NOTE[case.verdict])})"
    lines = [head, f"verdict: {case.verdict.value}  level: {case.level.value}  clauses: {', '.join(case.clauses)}"]
    if case.verdict is not Verdict.PASS:
        lines += [_("clause {id}").format(id=t.id) + f"{f' ({t.level})' if t.level else ''}: {t.text}"
                  for t in judged_texts(case) if t.text]
    if case.root_cause:
        rc = (root_causes or {}).get(case.root_cause)
        lines.append(_("root cause: {id}").format(id=case.root_cause)
                     + (f" [{', '.join(rc.clauses)}] {one_line(rc.title)}" if rc else ""))
    if case.pcap:
        lines.append(f"pcap: {case.pcap}")
    return lines


def case_body(case: CaseResult, root_causes: dict[str, RootCause] | None = None) -> str:
    """The evidence of one case as plain text (failure/error body, system-out)."""
    lines = case_meta(case, root_causes)
    for label, value in ((_("requirement"), case.requirement), (_("expected"), case.expected),
                         (_("observed"), case.observed)):
        if value:
            lines.append(f"{label}: {value}")
    for label, value in ((_("sent (hex):"), case.sent_hex), (_("received (hex):"), case.received_hex)):
        if value:
            lines.append(label)
            lines.extend("  " + row for row in group_hex(value, limit=HEX_LIMIT).splitlines())
    for key, value in sorted(case.details.items(), key=lambda kv: str(kv[0])):
        text = str(value)
        if len(text) > DETAIL_LIMIT:
            text = text[:DETAIL_LIMIT] + _("… ({n} characters)").format(n=len(text))
        lines.append(f"{key}: {text}")
    return "\n".join(lines)


def _fmt_time(seconds: float) -> str:
    return f"{max(0.0, seconds):.3f}"


def _id_list(ids: Sequence[str]) -> str:
    shown = " ".join(ids[:LIST_LIMIT])
    return shown + (f" … ({len(ids)} in all)" if len(ids) > LIST_LIMIT else "") if ids else "none"


def suite_text(suite: SuiteInfo, cases: list[CaseResult], root_causes: Sequence[RootCause]) -> str:
    """The suite's system-out: overall line, root causes, NON-STRICT cases, cases not run."""
    lines = [overall_line(cases, suite)]
    for rc in root_causes:
        lines.append(_("root cause {id} [{clauses}] {title} ({n} cases)").format(
            id=rc.id, clauses=", ".join(rc.clauses), title=one_line(rc.title), n=len(rc.cases)))
    nonstrict = [c for c in cases if c.verdict is Verdict.NON_STRICT]
    if nonstrict:
        lines.append(_("{n} NON-STRICT (a SHOULD is broken; these cases pass in CI):").format(n=len(nonstrict)))
        lines += [f"  NON-STRICT {c.id} [{', '.join(c.clauses)}] {one_line(c.message, 200)}" for c in nonstrict]
    if not suite.complete:
        lines.append(_("not run ({n}): {ids}").format(n=len(suite.not_run), ids=_id_list(suite.not_run)))
    return "\n".join(lines)


def build_junit(suite: SuiteInfo, cases: list[CaseResult], root_causes: Sequence[RootCause] = (),
                acceptance: dict[str, Any] | None = None) -> ET.Element:
    """The JUnit document as an ElementTree element (``<testsuites>``); an acceptance package's run ID and device
    under test are properties too (``run_id``, ``dut.<key>``)."""
    t = totals(cases)
    counts = {
        "tests": str(len(cases)),
        "failures": str(t[Verdict.FAIL.value]),
        "errors": str(t[Verdict.ERROR.value]),
    }
    skipped = str(t[Verdict.SKIP.value] + t[Verdict.INCONCLUSIVE.value])
    time = _fmt_time(suite.duration_s)
    root = ET.Element("testsuites", {"name": SUITE_NAME, **counts, "time": time})  # junit-10: no skipped here
    ts = _sub(root, "testsuite", name=SUITE_NAME, **counts, skipped=skipped, time=time,
              timestamp=junit_timestamp(suite.started))

    info = suite_dict(suite)
    with i18n.language("en"):  # a machine-read property: the same words in every language
        overall_english = overall_line(cases, suite)
    props = _sub(ts, "properties")
    suite_props: list[tuple[str, Any]] = [
        ("version", suite.version), ("registry_version", info["registry_version"] or "none"),
        ("started", suite.started), ("target", suite.target),
        ("udp_target", suite.udp_target or "none"), ("extension", suite.extension),
        ("expected_failures", suite.expected_failures or "none"), ("command", suite.command),
        ("complete", str(suite.complete).lower()), ("lang", i18n.current()),
        ("overall", overall_english),
    ]
    if not suite.complete:
        suite_props += [("cases_total", max(suite.cases_total, len(cases))), ("not_run", _id_list(suite.not_run))]
    suite_props += [(f"profile.{k}", getattr(v, "value", v)) for k, v in suite.profile.items()]
    suite_props += [(f"totals.{k}", n) for k, n in t.items()]
    suite_props.append(("nonstrict", _id_list([c.id for c in cases if c.verdict is Verdict.NON_STRICT])))
    suite_props += [(f"root_cause.{rc.id}", f"{', '.join(rc.clauses)}: {one_line(rc.title, 300)} ({len(rc.cases)} cases)")
                    for rc in root_causes]
    if acceptance:
        suite_props += [("run_id", acceptance.get("run_id", ""))]
        suite_props += [(f"dut.{k}", v) for k, v in (acceptance.get("dut") or {}).items()]
    for name, value in suite_props:
        _sub(props, "property", name=name, value=value)

    by_id = {rc.id: rc for rc in root_causes}
    for case in cases:
        tc = _sub(ts, "testcase", name=one_line(f"{case.id} {case.title}", 300),
                  classname=f"isight.{family_of(case)}", time=_fmt_time(case.duration_s))
        message = one_line(case.message or case.verdict.value)
        body = case_body(case, by_id)
        v = case.verdict
        if v is Verdict.FAIL:
            _sub(tc, "failure", body, message=message, type="FAIL")
        elif v is Verdict.ERROR:
            _sub(tc, "error", body, message=message, type="ERROR")
        elif v is Verdict.SKIP:
            _sub(tc, "skipped", message=message)
        elif v is Verdict.INCONCLUSIVE:
            _sub(tc, "skipped", message=one_line(_("INCONCLUSIVE (could not be judged): {message}").format(
                message=case.message)))
        # the evidence is in the failure/error body; system-out says what the case is about
        _sub(tc, "system-out", "\n".join(case_meta(case, by_id)) if v.failing else body)
    _sub(ts, "system-out", suite_text(suite, cases, root_causes))
    return root


def junit_bytes(suite: SuiteInfo, cases: list[CaseResult], root_causes: Sequence[RootCause] = (),
                acceptance: dict[str, Any] | None = None) -> bytes:
    root = build_junit(suite, cases, root_causes, acceptance)
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="utf-8", xml_declaration=True) + b"\n"


def write_junit(path: str | os.PathLike[str], suite: SuiteInfo, cases: list[CaseResult],
                root_causes: Sequence[RootCause] = (), acceptance: dict[str, Any] | None = None) -> None:
    """Write junit.xml atomically."""
    atomic_write_bytes(path, junit_bytes(suite, cases, root_causes, acceptance))
