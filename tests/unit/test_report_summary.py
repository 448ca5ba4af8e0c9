"""summary.json, totals, clause verdicts, the overall line, and the shared text helpers.

``sample_suite`` and ``sample_cases`` are the synthetic results the other report tests
import: one case per verdict, hostile strings, a pcap, a latency series, a wire log.
"""

from __future__ import annotations

import json
import os
import re

import pytest

from conformance.model.verdicts import VERDICT_ORDER, CaseResult, Level, RootCause, SuiteInfo, Verdict, WireLine
from conformance.protocol import DEFAULT_PROFILE
from conformance.report import by_clause, conforms, overall_line, totals, write_summary
from conformance.report.summary import (
    CLAUSES,
    FAMILIES,
    clean_text,
    format_duration,
    group_hex,
    hex_bytes,
    registry_version,
    worst,
)

HOSTILE = "<script>alert('x')</script> & \x00\x1b[31m\ud800 ]]> [bold]markup[/]"


def sample_suite(**changes) -> SuiteInfo:
    info = SuiteInfo(
        version="0.1.0", started="2026-05-09T07:35:25.120000+00:00", duration_s=187.4,
        target="10.0.0.5:9004", profile=DEFAULT_PROFILE.replace(first_index=1).to_dict(),
        udp_target=None, extension="detected", expected_failures=None,
        command="isight-conformance run --target 10.0.0.5:9004 --first-index 1",
    )
    for key, value in changes.items():
        setattr(info, key, value)
    return info


def _wire(n: int) -> list[WireLine]:
    lines = [WireLine(0.0, 1, "·", "connect", "", "connected (command)")]
    for i in range(n):
        if i % 2 == 0:
            lines.append(WireLine(i * 1.5, 1, "→", "send", "fefe00010123010100190000" + "00" * 25 + "0000", f"pose #{i}"))
        else:
            lines.append(WireLine(i * 1.5 + 0.4, 1, "←", "recv", "fefe000110230000000000000000", "answer 23/0000"))
    return lines


def sample_cases() -> list[CaseResult]:
    """One case per verdict (plus a second PASS), in run order."""
    return [
        CaseResult("F1-01", "Wrong start word is not answered 0000", ("F1", "R1"), Level.MUST, Verdict.FAIL, 0.051,
                   message="box answered 0000 to a frame starting FF FE",
                   requirement="R1: never answer 0000 to a frame that breaks F",
                   expected="no answer, a non-zero error, or close", observed="answer 23/0000 after 3.1 ms",
                   sent_hex="fffe0001012301010019" + "00" * 27, received_hex="fefe000110230000000000000000",
                   pcap="pcaps/F1-01.pcapng", wire=_wire(6)),
        CaseResult("A3-02", "Unparsable pose is answered 1001", ("A3",), Level.SHOULD, Verdict.NON_STRICT, 0.02,
                   message=HOSTILE, expected="1001", observed="0002", wire=_wire(3)),
        CaseResult("T2-01", "Stream at 50 Hz without backlog", ("T2", "S6"), Level.MUST, Verdict.PASS, 3.0,
                   message="150 poses answered", latencies_ms=[2.0 + (i % 7) * 0.3 for i in range(150)],
                   wire=_wire(10)),
        CaseResult("S2-01", "CycleOn on a ready box", ("S2",), Level.MUST, Verdict.INCONCLUSIVE, 0.3,
                   message="box answered 0001 (not ready)"),
        CaseResult("S3-02", "CycleOff without CycleOn", ("S3",), Level.MAY, Verdict.INFORMATIONAL, 0.01,
                   message="answered 0002"),
        CaseResult("F7-01", "UDP CRC check", ("F7",), Level.MUST, Verdict.SKIP, 0.0, message="no --udp-target"),
        CaseResult("R5-03", "Hundreds of idle connections", ("R5",), Level.MUST, Verdict.ERROR, 1.2,
                   message="OSError: too many open files (suite side)", details={"traceback": "Traceback ...\nOSError"}),
        CaseResult("B3-01", "Indexes rise by one", ("B3",), Level.MUST, Verdict.PASS, 0.01, wire=_wire(2)),
    ]


def sample_root_causes() -> tuple[list[CaseResult], list[RootCause]]:
    """A systematic defect: every answer's version swapped. RC1 explains 12 FAILs and 2
    NON-STRICTs; one FAIL and the rest of the sample are not explained by it."""
    cases = sample_cases()
    explained = [
        CaseResult(f"A5-01[v{i:02d}]", f"Frame {i} that is not a request", ("A5", "R1", "F2"), Level.MUST, Verdict.FAIL,
                   0.02, message=f"A5: a frame that is not a request MUST NOT be answered 0000: variant {i}",
                   requirement="A5: a frame that is not a request MUST NOT be answered 0000",
                   sent_hex="fefe0001" + "01" * 10, received_hex="fefe0100" + "10" * 10, root_cause="RC1",
                   wire=_wire(4))
        for i in range(12)
    ] + [
        CaseResult(f"A3-01[g{i}]", "Gap in indexes", ("A3", "B3"), Level.SHOULD, Verdict.NON_STRICT, 0.02,
                   message="A3: a parse error SHOULD be answered 1001", root_cause="RC1")
        for i in range(2)
    ]
    rc = RootCause("RC1", ("F2", "A2"), "every answer carries version 01 00 instead of 00 01",
                   "fe fe 01 00 10 00 00 00 00 00 00 00 00 00", [c.id for c in explained], Level.MUST,
                   "malformed-answers")
    return cases[:1] + explained + cases[1:], [rc]


# -- totals / by_clause / overall ------------------------------------------------------
def test_totals_counts_every_verdict_worst_first():
    t = totals(sample_cases())
    assert list(t) == [v.value for v in VERDICT_ORDER]
    assert t == {"FAIL": 1, "ERROR": 1, "NON-STRICT": 1, "INCONCLUSIVE": 1, "INFORMATIONAL": 1, "SKIP": 1, "PASS": 2}
    assert totals([]) == {v.value: 0 for v in Verdict}


def test_worst_follows_verdict_order():
    assert worst([Verdict.PASS, Verdict.SKIP, Verdict.NON_STRICT]) is Verdict.NON_STRICT
    assert worst([Verdict.ERROR, Verdict.FAIL]) is Verdict.FAIL
    assert worst([]) is None


def test_clause_catalogue_matches_the_suites_clause_ids():
    from conformance.suite.record import CLAUSE_ID

    assert len(CLAUSES) == 37
    assert all(CLAUSE_ID.match(c) for c in CLAUSES)
    expected = [f"{f}{i}" for f, n in zip("FBASTRE", (7, 5, 5, 6, 2, 7, 5)) for i in range(1, n + 1)]
    assert list(CLAUSES) == expected
    assert not CLAUSE_ID.match("Z9") and not CLAUSE_ID.match("F8") and not CLAUSE_ID.match("F1 ")


def test_clause_table_is_a_view_of_the_registry():
    from conformance.protocol.clauses import all_clauses, families

    assert CLAUSES == {c.id: c.title for c in all_clauses().values()}
    assert FAMILIES == families() and list(FAMILIES) == list("FBASTRE")


def test_by_clause_worst_verdict_case_ids_and_untested():
    cases = sample_cases() + [
        CaseResult("R1-02", "Bad version", ("R1",), Level.MUST, Verdict.PASS),
        CaseResult("R1-03", "Bad version, SHOULD part", ("R1",), Level.SHOULD, Verdict.NON_STRICT),
        CaseResult("X-EXTRA", "a clause outside PROTOCOL.md", ("Z9", "Z9"), Level.MAY, Verdict.INFORMATIONAL),
    ]
    result = by_clause(cases)
    assert list(result)[:37] == list(CLAUSES)
    assert list(result)[37:] == ["Z9"]
    r1 = result["R1"]
    assert r1.verdict is Verdict.FAIL
    assert r1.cases == ("F1-01", "R1-02", "R1-03")
    assert r1.levels == {Level.MUST: Verdict.FAIL, Level.SHOULD: Verdict.NON_STRICT}
    assert result["T2"].verdict is Verdict.PASS and result["S6"].cases == ("T2-01",)
    assert result["F2"].verdict is None and not result["F2"].tested and result["F2"].cases == ()
    assert result["Z9"].cases == ("X-EXTRA",)  # a clause named twice by one case counts once
    assert result["F1"].title == CLAUSES["F1"]


@pytest.mark.parametrize(("verdicts", "line", "ok"), [
    ([Verdict.PASS, Verdict.NON_STRICT], "CONFORMS (no FAIL/ERROR); 1 NON-STRICT", True),
    ([Verdict.PASS], "CONFORMS (no FAIL/ERROR); 0 NON-STRICT", True),
    ([Verdict.PASS, Verdict.INCONCLUSIVE], "CONFORMS (no FAIL/ERROR); 0 NON-STRICT; 1 INCONCLUSIVE (not judged)", True),
    ([Verdict.FAIL, Verdict.FAIL, Verdict.NON_STRICT], "DOES NOT CONFORM: 2 FAIL, 0 ERROR; 1 NON-STRICT", False),
    ([Verdict.ERROR, Verdict.PASS], "DOES NOT CONFORM: 0 FAIL, 1 ERROR; 0 NON-STRICT", False),
    ([Verdict.SKIP, Verdict.INCONCLUSIVE], "NOT JUDGED: no case reached a verdict (1 SKIP, 1 INCONCLUSIVE)", False),
    ([], "NOT JUDGED: no case ran", False),
])
def test_overall_line(verdicts, line, ok):
    cases = [CaseResult(f"C-{i:02d}", "t", ("F1",), Level.MUST, v) for i, v in enumerate(verdicts)]
    assert overall_line(cases) == line
    assert conforms(cases) is ok


# -- summary.json ------------------------------------------------------------------------
def test_write_summary_shape(tmp_path):
    suite, cases = sample_suite(), sample_cases()
    path = tmp_path / "out" / "summary.json"
    returned = write_summary(path, suite, cases)
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc == returned
    assert list(doc) == ["suite", "root_causes", "cases", "totals"]
    assert doc["root_causes"] == []
    assert list(doc["suite"])[:5] == ["version", "started", "duration_s", "target", "profile"]
    assert set(doc["suite"]) == {"version", "started", "duration_s", "target", "profile", "udp_target", "extension",
                                 "expected_failures", "command", "role", "complete", "cases_total", "not_run",
                                 "registry_version", "lanes", "lang"}
    assert doc["suite"]["registry_version"] == registry_version()
    assert all(case["clauses"] for case in doc["cases"])
    assert doc["suite"]["profile"]["tcp_check"] == "zero-or-crc"
    assert doc["suite"]["profile"]["first_index"] == 1
    assert doc["cases"] == json.loads(json.dumps([c.to_summary() for c in cases]))
    assert doc["totals"] == totals(cases)
    assert set(doc["totals"]) == {v.value for v in Verdict}


def test_write_summary_root_causes_and_registry_version(tmp_path):
    cases, rcs = sample_root_causes()
    doc = write_summary(tmp_path / "summary.json", sample_suite(registry_version="7"), cases, rcs)
    assert doc["suite"]["registry_version"] == "7"  # a version the run set is kept
    assert doc["root_causes"] == [rcs[0].to_dict()]
    assert doc["root_causes"][0]["cases"][0] == "A5-01[v00]"
    assert {c["id"]: c["root_cause"] for c in doc["cases"]}["A5-01[v11]"] == "RC1"


def test_write_summary_survives_hostile_text(tmp_path):
    case = sample_cases()[1]
    assert "\ud800" in case.message
    doc = write_summary(tmp_path / "summary.json", sample_suite(), [case])
    raw = (tmp_path / "summary.json").read_bytes()
    raw.decode("utf-8")  # valid UTF-8: the lone surrogate is a JSON escape
    assert json.loads(raw)["cases"][0]["message"] == doc["cases"][0]["message"] == case.message


def test_write_summary_is_atomic(tmp_path, monkeypatch):
    path = tmp_path / "summary.json"
    write_summary(path, sample_suite(), sample_cases())
    before = path.read_bytes()

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError, match="disk full"):
        write_summary(path, sample_suite(), [])
    assert path.read_bytes() == before  # the old file is intact
    assert os.listdir(tmp_path) == ["summary.json"]  # and no temp file is left behind


def test_write_summary_replaces_and_leaves_no_temp_files(tmp_path):
    path = tmp_path / "summary.json"
    write_summary(path, sample_suite(), sample_cases())
    write_summary(path, sample_suite(), [])
    assert json.loads(path.read_text())["cases"] == []
    assert os.listdir(tmp_path) == ["summary.json"]


# -- text helpers ------------------------------------------------------------------------
def test_clean_text_makes_control_characters_visible():
    assert clean_text("ok → fine\tand\nnew") == "ok → fine\tand\nnew"
    assert clean_text("a\x00b\x1bc\x7f\x85") == "a\\x00b\\x1bc\\x7f\\x85"
    assert clean_text("lone \ud800 and \uffff") == "lone \\ud800 and \\uffff"
    assert clean_text(12) == "12"
    assert not re.search("[\x00-\x08\x0b\x0c\x0e-\x1f]", clean_text(HOSTILE))


def test_group_hex():
    assert hex_bytes("FE FE:00-01") == ["fe", "fe", "00", "01"]
    assert hex_bytes("xyz") is None and hex_bytes("abc") is None
    assert group_hex("fefe0001", per_line=0) == "fe fe 00 01"
    assert group_hex("00" * 20, per_line=16) == " ".join(["00"] * 16) + "\n" + " ".join(["00"] * 4)
    assert group_hex("00" * 10, per_line=0, limit=4) == "00 00 00 00 … (10 bytes in all, first 4 shown)"
    assert group_hex("not hex\x00") == "not hex\\x00"


def test_format_duration():
    assert format_duration(0.0123) == "12 ms"
    assert format_duration(12.34) == "12.3 s"
    assert format_duration(187.4) == "3 min 07 s"
    assert format_duration(3723) == "1 h 02 min 03 s"
