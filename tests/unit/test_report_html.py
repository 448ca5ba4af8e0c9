"""report.html: well-formed, self-contained, escaped, and carrying what an integrator signs."""

from __future__ import annotations

import os
import re
import time
from html.parser import HTMLParser
from importlib import resources

from markupsafe import escape

from conformance.model.verdicts import CaseResult, Level, Verdict, WireLine
from conformance.report import render_html, write_html
from conformance.report.clausetext import clause_text
from conformance.report.diff import compare
from conformance.report.html import WIRE_HEAD, WIRE_TAIL, pcap_href
from conformance.report.html_cases import PRINT_CARDS, WIRE_PRINT_HEAD, WIRE_PRINT_TAIL
from conformance.report.summary import CLAUSES, registry_version, write_summary
from tests.unit.test_report_summary import sample_cases, sample_root_causes, sample_suite

VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}


class Checker(HTMLParser):
    """Checks nesting and collects what the tests look at."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.links: list[tuple[str, str]] = []  # (attribute, value) of every src/href
        self.details: dict[str, bool] = {}  # id -> open
        self.scripts = 0
        self.text: list[str] = []
        self.rows: list[list[str]] = []  # clause table rows: [clause, title, result...]
        self._in_clauses = False
        self._row: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        for name in ("src", "href", "xlink:href", "action", "data"):
            if name in a:
                self.links.append((name, a[name] or ""))
        if tag == "details":
            self.details[a.get("id")] = "open" in a
        if tag == "script":
            self.scripts += 1
            if "src" in a:
                self.errors.append("external script")
        if tag == "table" and "clauses" in (a.get("class") or ""):
            self._in_clauses = True
        if self._in_clauses and tag == "tr":
            self._row = []
        if tag not in VOID:
            self.stack.append(tag)

    def handle_startendtag(self, tag, attrs):
        self.handle_starttag(tag, attrs)
        if tag not in VOID:
            self.stack.pop()

    def handle_endtag(self, tag):
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes <{self.stack[-1] if self.stack else None}>")
            return
        self.stack.pop()
        if tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None
        if tag == "table":
            self._in_clauses = False

    def handle_data(self, data):
        self.text.append(data)
        if self._row is not None and data.strip():
            self._row.append(data.strip())


def _check(html: str) -> Checker:
    checker = Checker()
    checker.feed(html)
    checker.close()
    assert checker.errors == []
    assert checker.stack == [], f"unclosed: {checker.stack}"
    return checker


def _render(tmp_path, cases=None, root_causes=(), diff=None, **suite_changes) -> tuple[str, Checker]:
    path = tmp_path / "out" / "report.html"
    write_html(path, sample_suite(**suite_changes), sample_cases() if cases is None else cases, pcap_base=tmp_path,
               root_causes=root_causes, diff=diff)
    html = path.read_text(encoding="utf-8")
    return html, _check(html)


def test_well_formed_and_self_contained(tmp_path):
    html, checker = _render(tmp_path)
    assert html.startswith("<!DOCTYPE html>")
    for attr, value in checker.links:
        assert not re.match(r"^\s*(https?:|//|javascript:|data:)", value, re.IGNORECASE), (attr, value)
    assert not re.search(r"<(link|img|iframe|object|embed)\b", html)
    assert "@import" not in html and "url(" not in html
    assert checker.scripts == 1  # our small inline filter script, nothing else


def test_hostile_strings_are_escaped(tmp_path):
    html, checker = _render(tmp_path)
    assert "<script>alert(" not in html
    assert "&lt;script&gt;alert(" in html
    assert "[bold]markup[/]" in html
    assert "\\x00\\x1b[31m\\ud800" in html  # control characters and surrogates made visible
    assert not re.search("[\x00-\x08\x0b\x0c\x0e-\x1f]", html)


def test_header_for_signing(tmp_path):
    html, checker = _render(tmp_path)
    text = " ".join(" ".join(checker.text).split())
    assert "DOES NOT CONFORM: 1 FAIL, 1 ERROR; 1 NON-STRICT; 1 INCONCLUSIVE (not judged)" in text
    assert 'class="overall o-fails"' in html
    for needle in ("10.0.0.5:9004", "isight-conformance 0.1.0", "2026-05-09 07:35:25 UTC", "3 min 07 s",
                   "implemented (detected)", "isight-conformance run --target 10.0.0.5:9004 --first-index 1",
                   "none: UDP cases (F7, R7) are SKIP", "Tested by", "Signature", "Date"):
        assert needle in text, needle
    # the one non-default setting is highlighted
    assert f"isight-conformance 0.1.0 · clause registry version {registry_version()}" in text
    changed = re.findall(r'<tr class="changed"><td class="mono">(\w+)</td>', html)
    assert changed == ["first_index"]
    assert "1 setting differs from PROTOCOL.md's defaults" in text


def test_overall_line_when_conforming(tmp_path):
    cases = [c for c in sample_cases() if c.verdict in (Verdict.PASS, Verdict.NON_STRICT)]
    html, checker = _render(tmp_path, cases=cases)
    assert "CONFORMS (no FAIL/ERROR); 1 NON-STRICT" in html
    assert 'class="overall o-conforms"' in html


def test_clause_table_lists_every_clause(tmp_path):
    html, checker = _render(tmp_path)
    rows = {r[0]: r for r in checker.rows if r and r[0] in CLAUSES}
    assert set(rows) == set(CLAUSES)
    assert rows["F2"][2] == "not tested"
    assert rows["F1"][2] == "FAIL" and "F1-01" in rows["F1"]
    assert rows["R1"][2] == "FAIL"
    assert rows["A3"][2] == "NON-STRICT" and rows["A3"][3:5] == ["–", "NON-STRICT"]
    assert rows["T2"][2] == "PASS" and "T2-01" in rows["T2"]
    assert rows["R5"][2] == "ERROR"
    assert '<a class="chip v-FAIL" href="#case-F1-01">F1-01</a>' in html


def test_a_clause_whose_cases_judged_another_clause_is_not_judged(tmp_path):
    case = CaseResult("S4-01", "two connections", ("S4", "F2"), Level.MUST, Verdict.FAIL, judged=("F2",),
                      message="F2: the answer is malformed")
    html, checker = _render(tmp_path, cases=[case])
    rows = {r[0]: r for r in checker.rows if r and r[0] in CLAUSES}
    assert rows["S4"][2] == "not judged" and rows["F2"][2] == "FAIL" and rows["F1"][2] == "not tested"
    assert "(not judged, their cases ended on another clause: S4)" in _text(checker)


def test_cases_expanded_unless_pass(tmp_path):
    html, checker = _render(tmp_path)
    for case in sample_cases():
        anchor = "case-" + case.id
        assert checker.details[anchor] is (case.verdict is not Verdict.PASS), case.id
    assert html.index("case-F1-01") < html.index("case-B3-01")  # run order


def test_case_content(tmp_path):
    html, checker = _render(tmp_path)
    text = " ".join(checker.text)
    assert "R1: never answer 0000 to a frame that breaks F" in text
    assert "no answer, a non-zero error, or close" in text and "answer 23/0000 after 3.1 ms" in text
    assert "0000  ff fe 00 01 01 23 01 01  00 19 00 00 00 00 00 00" in text  # hexdump, grouped in bytes
    assert "0000  fe fe 00 01 10 23 00 00  00 00 00 00 00 00" in text
    assert "Wire log (7 lines)" in text
    assert "connected (command)" in text and "→" in text and "←" in text
    assert "traceback" in text  # details of the ERROR case
    assert html.count("<svg") == 1  # only T2-01 has latencies
    assert "T2-01: answer latency per request" in html


def test_pcap_link_is_relative_to_the_report(tmp_path):
    html, checker = _render(tmp_path)
    assert ("href", "../pcaps/F1-01.pcapng") in checker.links
    report_dir = tmp_path / "out"
    assert pcap_href(str(tmp_path / "cap dir" / "a.pcapng"), report_dir, None) == "../cap%20dir/a.pcapng"
    assert pcap_href("x.pcapng", report_dir, report_dir) == "x.pcapng"
    assert not pcap_href("javascript:alert(1)", report_dir, report_dir).startswith("javascript:")


def test_long_wire_log_is_cut_with_a_note(tmp_path):
    wire = [WireLine(i, 1, "→", "send", "fefe", f"line {i}") for i in range(2000)]
    case = CaseResult("R4-01", "many frames", ("R4",), Level.MUST, Verdict.FAIL, wire=wire)
    html, checker = _render(tmp_path, cases=[case])
    assert html.count("<tr class=\"sent") == WIRE_HEAD + WIRE_TAIL
    assert f"… {2000 - WIRE_HEAD - WIRE_TAIL} lines omitted here" in html
    assert "line 0<" in html and "line 1999<" in html and "line 1000<" not in html
    # on paper: the first and last few lines, and a note
    assert html.count("<tr class=\"sent\">") == WIRE_PRINT_HEAD + WIRE_PRINT_TAIL
    assert f"… {2000 - WIRE_PRINT_HEAD - WIRE_PRINT_TAIL} lines not printed" in html


def test_no_cases(tmp_path):
    html, checker = _render(tmp_path, cases=[])
    assert "NOT JUDGED: no case ran" in html
    assert "No case ran." in html


def test_write_is_atomic(tmp_path):
    _render(tmp_path)
    _render(tmp_path, cases=[])
    assert os.listdir(tmp_path / "out") == ["report.html"]


def test_template_is_package_data():
    assert resources.files("conformance.report").joinpath("templates/report.html.j2").is_file()


def test_large_run_renders_quickly(tmp_path):
    """300 cases with 2,000 wire lines each; prints the time, asserts none."""
    wire = [WireLine(i * 0.5, 1 + i % 2, "→" if i % 2 == 0 else "←", "send" if i % 2 == 0 else "recv",
                     "fefe00010123010100190000" + "ab" * 25 + "0000", f"pose {i}") for i in range(2000)]
    verdicts = list(Verdict)
    cases = [CaseResult(f"R1-{i:03d}", f"case {i}", ("R1",), Level.MUST, verdicts[i % len(verdicts)], 0.1,
                        message="m", wire=wire, latencies_ms=[float(i % 50)] * 2000 if i % 10 == 0 else [])
             for i in range(300)]
    start = time.perf_counter()
    html = render_html(sample_suite(), cases, tmp_path)
    elapsed = time.perf_counter() - start
    print(f"\nrender_html: 300 cases x 2,000 wire lines in {elapsed:.2f} s, {len(html) / 1e6:.1f} MB")
    assert html.count("<details") == 300


def test_a_robot_certification_report_names_the_robot() -> None:
    from tests.unit.test_report_summary import sample_cases, sample_suite

    html = render_html(sample_suite(role="robot", target="robot at 127.0.0.1:9004 (client role)"), sample_cases())
    assert "Robot (client role) tested" in html and "The robot at" in html
    assert "The AI Box at" not in html and "Vision AI Box (server role)" not in html


def _text(checker: Checker) -> str:
    return " ".join(" ".join(checker.text).split())


def _details_classes(html: str) -> dict[str, str]:
    return dict((m.group(2), m.group(1)) for m in re.finditer(r'<details class="case ([^"]*)" id="([^"]+)"', html))


def test_document_order_for_print(tmp_path):
    """What was tested, the overall result, the sign-off, root causes, findings, clause table, then cases."""
    cases, rcs = sample_root_causes()
    html, _ = _render(tmp_path, cases=cases, root_causes=rcs)
    marks = ['id="top"', 'id="overall"', 'id="signoff"', 'id="root-causes"', 'id="findings"', 'id="clauses"',
             'id="totals"', 'id="cases"']
    positions = [html.index(m) for m in marks]
    assert positions == sorted(positions)


def test_root_causes_lead_and_group_the_findings(tmp_path):
    cases, rcs = sample_root_causes()
    html, checker = _render(tmp_path, cases=cases, root_causes=rcs)
    text = _text(checker)
    assert "Root causes (1)" in text
    assert "every answer carries version 01 00 instead of 00 01" in text
    assert "explains 14 cases: 12 FAIL, 2 NON-STRICT" in text
    assert f"F2 ({clause_text('F2').level}): {clause_text('F2').text}" in text
    assert "0000 fe fe 01 00 10 00 00 00 00 00 00 00 00 00" in text  # the evidence as a hexdump
    findings = html[html.index('id="findings"'):html.index('id="clauses"')]
    rc_group = findings.index("RC1</a>: every answer carries")
    rest = findings.index("Not explained by a root cause (4 cases)")
    assert rc_group < findings.index("A5-01[v00]") < rest < findings.index("F1-01")
    assert findings.index("A5-01[v11]") < findings.index("A3-01[g0]") < rest  # worst first in a group
    for absent in ("T2-01", "S3-02", "F7-01", "B3-01"):  # PASS, INFORMATIONAL and SKIP are not findings
        assert absent not in findings
    assert "1 INFORMATIONAL and 1 SKIP cases are listed with all cases" in text


def test_cases_a_root_cause_explains_are_one_click_away(tmp_path):
    cases, rcs = sample_root_causes()
    html, checker = _render(tmp_path, cases=cases, root_causes=rcs)
    assert checker.details["case-A5-01_v00_"] is True  # the first one is its example
    assert all(checker.details[f"case-A5-01_v{i:02d}_"] is False for i in range(1, 12))
    assert checker.details["case-F1-01"] is True and checker.details["case-T2-01"] is False
    assert "openTarget" in html  # a link to a closed case opens it


def test_print_cards(tmp_path):
    cases, rcs = sample_root_causes()
    html, _ = _render(tmp_path, cases=cases, root_causes=rcs)
    classes = _details_classes(html)
    cards = {anchor for anchor, cls in classes.items() if "card" in cls.split()}
    # FAIL/ERROR/NON-STRICT/INCONCLUSIVE with a finding of their own, and the first case of RC1
    assert cards == {"case-F1-01", "case-A5-01_v00_", "case-A3-02", "case-S2-01", "case-R5-03"}
    # the other findings print under Findings only; PASS, INFORMATIONAL and SKIP print one line each
    assert "pextra" in classes["case-A5-01_v01_"].split() and "pextra" in classes["case-A3-01_g0_"].split()
    for anchor in ("case-T2-01", "case-S3-02", "case-F7-01"):
        assert not {"pextra", "card"} & set(classes[anchor].split())
    css = html[html.index("@media print"):html.index("</style>")]
    assert "details.case:not(.card) > .case-body { display: none; }" in css
    assert ".pextra { display: none !important; }" in css


def test_print_cards_group_repeated_findings_and_are_bounded(tmp_path):
    same = [CaseResult(f"R1-10[tc{i}]", "vector", ("R1",), Level.MUST, Verdict.FAIL,
                       message=f"R1: vector tc{i} breaks F1 and MUST NOT be answered 0000: expected silence")
            for i in range(30)]
    distinct = [CaseResult(f"X{i}", "t", ("A1",), Level.MUST, Verdict.FAIL, message=f"A1: finding {'abcdefghijklmnopqrstuvwxyz'[i % 26] * (1 + i // 26)}: expected x")
                for i in range(PRINT_CARDS + 10)]
    html, _ = _render(tmp_path, cases=same + distinct)
    cards = [a for a, cls in _details_classes(html).items() if "card" in cls.split()]
    assert cards[0] == "case-R1-10_tc0_" and "case-R1-10_tc1_" not in cards  # one card for one finding
    assert len(cards) == PRINT_CARDS


def test_non_pass_cases_show_their_clause_text(tmp_path):
    html, checker = _render(tmp_path)
    text = _text(checker)
    r1 = clause_text("R1")
    assert f"R1 ({r1.level}): {r1.text}" in text  # F1-01 judged R1
    body = html[html.index('id="case-A3-02"'):html.index('id="case-T2-01"')]
    assert str(escape(clause_text("A3").text)) in body
    passing = html[html.index('id="case-T2-01"'):html.index('id="case-S2-01"')]
    assert 'class="clause-texts' not in passing


def test_clause_table_on_paper_names_only_cases_that_did_not_pass(tmp_path):
    html, _ = _render(tmp_path)
    t2 = html[html.index('<td class="cid">T2</td>'):]
    t2 = t2[:t2.index("</tr>")]
    assert 'class="chip v-PASS pextra"' in t2 and "1 case: 1 PASS" in t2
    f1 = html[html.index('<td class="cid">F1</td>'):]
    f1 = f1[:f1.index("</tr>")]
    assert '<a class="chip v-FAIL" href="#case-F1-01">' in f1 and "1 case: 1 FAIL" in f1


def test_incomplete_run(tmp_path):
    not_run = [f"R2-{i:02d}" for i in range(40)]
    html, checker = _render(tmp_path, complete=False, cases_total=48, not_run=not_run)
    text = _text(checker)
    assert "INCOMPLETE (8 of 48 cases run)" in text and "CONFORMS" not in text
    assert 'class="overall o-fails"' in html  # it failed so far
    assert "8 run of 48 selected" in text
    assert "40 cases: R2-00, R2-01" in text and "R2-29 … and 10 more" in text and "R2-30" not in text
    passing = [c for c in sample_cases() if c.verdict is Verdict.PASS]
    html, _ = _render(tmp_path, cases=passing, complete=False, cases_total=10, not_run=["S4-01"])
    assert 'class="overall o-incomplete"' in html and "INCOMPLETE (2 of 10 cases run)" in html


def test_baseline_section(tmp_path):
    old_cases = sample_cases()
    new_cases = [CaseResult(c.id, c.title, c.clauses, c.level,
                            {"B3-01": Verdict.FAIL, "F1-01": Verdict.PASS}.get(c.id, c.verdict), message=c.message)
                 for c in old_cases]
    old = write_summary(tmp_path / "old.json", sample_suite(), old_cases)
    new = write_summary(tmp_path / "new.json", sample_suite(), new_cases)
    diff = compare(old, new, "old/summary.json", "new/summary.json")
    html, checker = _render(tmp_path, cases=new_cases, diff=diff)
    text = _text(checker)
    section = html[html.index('id="baseline"'):html.index('id="clauses"')]
    assert "Changes since the baseline run" in text and "Got worse:" in text
    assert "Got worse (1)" in section and "PASS → FAIL" in section and 'href="#case-B3-01"' in section
    assert "Got better (1)" in section and "FAIL → PASS" in section
    assert html.index('id="findings"') < html.index('id="baseline"') < html.index('id="clauses"')
    html, _ = _render(tmp_path)
    assert 'id="baseline"' not in html


def test_the_extension_line_says_what_detection_saw():
    from conformance.report.html import extension_meaning

    seen = "not implemented (detected: …; result request (27): transfer type 10, action 27, error 0x0003, no block)"
    assert extension_meaning(seen).startswith(seen) and "A5-02 judges 26/27" in extension_meaning(seen)
    assert extension_meaning("implemented (detected: 27: …)").endswith(": E cases run")
    assert extension_meaning("off") == "switched off by the command line: E cases SKIP"
