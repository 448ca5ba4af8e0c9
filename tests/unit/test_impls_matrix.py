"""The matrix tool's judgement and report parsing (no suite run: synthetic summary.json files)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tests.impls.expectations import EXPECTATIONS, RANDOM, expectation, judge
from tests.impls.matrix import Row, _read_summary, box_seed, format_table, main, sample_seeds, target_args


def _summary(tmp: Path, cases: list[dict[str, object]], root_causes: list[dict[str, object]] | None) -> Path:
    totals: dict[str, int] = {}
    for c in cases:
        totals[str(c["verdict"])] = totals.get(str(c["verdict"]), 0) + 1
    doc: dict[str, object] = {"suite": {}, "cases": cases, "totals": totals}
    if root_causes is not None:
        doc["root_causes"] = root_causes
    report = tmp / "report"
    report.mkdir(parents=True)
    (report / "summary.json").write_text(json.dumps(doc))
    return report


def _case(cid: str, verdict: str, clauses: list[str], root: str | None = None) -> dict[str, object]:
    return {"id": cid, "verdict": verdict, "clauses": clauses, "root_cause": root}


def test_judge_conforming_and_broken() -> None:
    ok, bad = EXPECTATIONS["resync-fine"], EXPECTATIONS["swapped-version"]
    assert judge(ok, 0, {"PASS": 10}, []) == "ok"
    assert judge(ok, 1, {"FAIL": 2, "PASS": 8}, []).startswith("FALSE ALARM")
    assert judge(ok, 0, {"NON-STRICT": 1}, []).startswith("FALSE ALARM")
    assert judge(bad, 0, {"PASS": 10}, []).startswith("MISSED")
    assert judge(bad, 1, {"FAIL": 1}, [{"clauses": ["F2"], "level": "MUST"}]) == "ok"
    assert judge(bad, 1, {"FAIL": 1}, [{"clauses": ["A5", "R1"], "level": "MUST"}]).startswith("WRONG CLAUSE (")
    assert judge(bad, 1, {"FAIL": 1}, None, ("A4", "T1")).startswith("WRONG CLAUSE?")
    assert judge(bad, None, {}, None).startswith("NO RESULT")
    nan = EXPECTATIONS["nan-zero"]
    assert judge(nan, 0, {"NON-STRICT": 3}, [{"clauses": ["B4"], "level": "SHOULD"}]) == "ok"
    assert judge(nan, 1, {"FAIL": 1, "NON-STRICT": 3}, [{"clauses": ["B4"], "level": "MUST"}]).startswith("WRONG LEVEL")
    assert judge(nan, 1, {"FAIL": 1, "NON-STRICT": 3}, None, ("B4",)).startswith("WRONG LEVEL?")


def test_read_summary_with_and_without_root_causes(tmp_path: Path) -> None:
    cases = [_case("T1-00", "PASS", ["A4"]), _case("F2-01", "FAIL", ["F2"], "RC1"),
             _case("A5-01[x]", "FAIL", ["A5", "R1"], "RC1"), _case("B4-01", "NON-STRICT", ["B4"]),
             _case("R6-01", "NON-STRICT", ["R6"])]
    report = _summary(tmp_path / "a", cases, [{"id": "RC1", "clauses": ["F2"], "title": "answers carry version 01 00",
                                               "evidence": "fe fe 01 00", "cases": ["F2-01", "A5-01[x]"],
                                               "level": "MUST"}])
    row = Row("swapped-version", "box", "broken", "F2 FAIL", exit=1)
    _read_summary(row, report)
    assert row.totals == {"PASS": 1, "FAIL": 2, "NON-STRICT": 2}
    assert row.first == ["F2-01 FAIL [F2] rc=RC1", "A5-01[x] FAIL [A5,R1] rc=RC1", "B4-01 NON-STRICT [B4]"]
    assert row.root_causes is not None and row.root_causes[0].startswith("RC1 [F2] MUST")
    assert row.judgement == "ok"
    old = Row("swapped-version", "box", "broken", "F2 FAIL", exit=1)
    _read_summary(old, _summary(tmp_path / "b", cases[2:], None))
    assert old.root_causes is None and old.judgement.startswith("WRONG CLAUSE?")
    assert "(no key)" in format_table([old]) and "| swapped-version |" in format_table([old])


def test_rejudge_rewrites_the_table(tmp_path: Path) -> None:
    (tmp_path / "nan-zero-0").mkdir()
    _summary(tmp_path / "nan-zero-0", [_case("B4-01", "NON-STRICT", ["B4"])], [])
    row = Row("nan-zero", "box", "broken", "B4 NON-STRICT", exit=0, judgement="stale")
    (tmp_path / "matrix.json").write_text(json.dumps([row.__dict__]))
    assert main(["--rejudge", str(tmp_path)]) == 1  # "ok?" is not "ok": no root_causes to check
    rows = json.loads((tmp_path / "matrix.json").read_text())
    assert rows[0]["judgement"] == "ok?" and "nan-zero" in (tmp_path / "matrix.md").read_text()
    assert main(["--rejudge", str(tmp_path / "missing")]) == 2


def test_target_args_read_every_address_and_flag_of_the_box_s_first_line() -> None:
    line = "listening tcp 127.0.0.1:4000 udp 127.0.0.1:4000 stream 127.0.0.1:4001 args --first-index 1 --checking lenient"
    assert target_args(line) == ["--target", "127.0.0.1:4000", "--udp-target", "127.0.0.1:4000", "--stream-target",
                                 "127.0.0.1:4001", "--first-index", "1", "--checking", "lenient"]
    assert target_args("listening tcp 127.0.0.1:4000") == ["--target", "127.0.0.1:4000"]


def test_samples_are_reproducible_and_each_names_its_box() -> None:
    assert sample_seeds(3, 5) == sample_seeds(3, 5) != sample_seeds(4, 5)
    assert sample_seeds(3, 8)[:5] == sample_seeds(3, 5)  # a longer sample starts with the shorter one
    random_box = expectation(RANDOM)
    assert random_box.conforming and box_seed(random_box, argparse.Namespace(base_seed=1), 42) == 42
    broken = EXPECTATIONS["swapped-version"]
    assert box_seed(broken, argparse.Namespace(base_seed=0), 1) is None  # the documented base
    assert box_seed(broken, argparse.Namespace(base_seed=5), 1) == box_seed(broken, argparse.Namespace(base_seed=5), 9)


def test_a_random_row_is_judged_clean_or_a_false_alarm(tmp_path: Path) -> None:
    report = _summary(tmp_path / "a", [_case("F6-02", "NON-STRICT", ["F6"])], [])
    row = Row(RANDOM, "box", "conforming", "clean", seed=7, exit=0)
    _read_summary(row, report)
    assert row.judgement.startswith("FALSE ALARM")
    assert main(["--sample", "1001"]) == 2 and main(["--base-seed", "-1"]) == 2
