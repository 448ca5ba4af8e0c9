"""What fleet.json says about each box (conformance/fleet/fleet_results.py), from real summary.json files."""

from __future__ import annotations

import json
from pathlib import Path

from conformance.fleet.fleet_results import box_entry, fleet_document, write_fleet_json
from conformance.model.verdicts import RootCause, Verdict
from tests.fleet_util import box_run, case

P, F = Verdict.PASS, Verdict.FAIL


def test_a_conforming_box(tmp_path: Path) -> None:
    entry = box_entry(box_run(tmp_path, "a", cases=[case("A4-01", P), case("F1-01", P)]), tmp_path)
    assert entry["status"] == "conforms" and entry["passed"]
    assert entry["overall"].startswith("CONFORMS")
    assert entry["totals"]["PASS"] == 2 and entry["totals"]["FAIL"] == 0
    assert entry["report"] == "a/report.html" and entry["summary"] == "a/summary.json"
    assert entry["pcaps"] == "a/pcaps" and entry["log"] == "a/run.log"
    assert entry["target"] == "bundled reference box at 127.0.0.1:40000"  # from the summary
    assert entry["exit_code"] == 0 and entry["duration_s"] == 12.5


def test_a_failing_box_carries_its_root_causes(tmp_path: Path) -> None:
    rc = RootCause("RC1", ("A5",), "answers unknown actions with 0000", "fefe 0001 10 63 …", ["A5-01", "A5-02"])
    run = box_run(tmp_path, "b", exit_code=1, root_causes=(rc,),
                  cases=[case("A5-01", F, "RC1"), case("A5-02", F, "RC1"), case("A4-01", P)])
    entry = box_entry(run, tmp_path)
    assert entry["status"] == "fails" and not entry["passed"]
    assert entry["failing"] == ["A5-01", "A5-02"]
    assert entry["overall"].startswith("DOES NOT CONFORM: 2 FAIL")
    (cause,) = entry["root_causes"]
    assert cause["id"] == "RC1" and cause["clauses"] == ["A5"] and cause["cases"] == ["A5-01", "A5-02"]
    assert cause["title"] == "answers unknown actions with 0000" and cause["evidence"].startswith("fefe")


def test_expected_failures_matched_and_not_matched(tmp_path: Path) -> None:
    cases = [case("T2-01", F), case("A4-01", P)]
    matched = box_entry(box_run(tmp_path, "m", exit_code=0, cases=cases, expected=("T2-01",)), tmp_path)
    assert matched["status"] == "expected failures" and matched["passed"]
    assert matched["expected_failures"] == ["T2-01"] and matched["unexpected_failures"] == []
    log = "isight-conformance run: the failing set differs from the expected-failures list; ...\n"
    other = box_entry(box_run(tmp_path, "n", exit_code=1, cases=cases, expected=("R5-02",), log=log), tmp_path)
    assert other["status"] == "fails" and not other["passed"]
    assert other["unexpected_failures"] == ["T2-01"] and other["unexpectedly_passing"] == ["R5-02"]
    assert other["message"].startswith("the failing set differs")


def test_a_box_whose_run_could_not_start_is_an_error_with_its_reason(tmp_path: Path) -> None:
    log = "some output\nisight-conformance run: target 10.0.0.5:9004 unreachable: connection refused\n"
    entry = box_entry(box_run(tmp_path, "c", exit_code=2, log=log, target="10.0.0.5:9004"), tmp_path)
    assert entry["status"] == "error" and not entry["passed"]
    assert entry["message"] == "target 10.0.0.5:9004 unreachable: connection refused"
    assert entry["target"] == "10.0.0.5:9004" and entry["report"] is None
    # exit 1 without a summary (the child died) is an error too, not "fails"
    dead = box_entry(box_run(tmp_path, "d", exit_code=1, log="Traceback ...\nKeyError: 'x'\n"), tmp_path)
    assert dead["status"] == "error" and dead["message"] == "KeyError: 'x'"


def test_interrupted_and_not_run_boxes(tmp_path: Path) -> None:
    cut = box_entry(box_run(tmp_path, "e", status="interrupted", exit_code=1, cases=[case("F1-01", P)]), tmp_path)
    assert cut["status"] == "interrupted" and not cut["passed"]
    assert cut["overall"] == "INTERRUPTED: the fleet run was stopped after 1 cases of this box"
    assert cut["report"] == "e/report.html"  # what it wrote is still linked
    waiting = box_entry(box_run(tmp_path, "f", status="not run", exit_code=None), tmp_path)
    assert waiting["status"] == "not run" and waiting["exit_code"] is None and waiting["report"] is None


def test_an_unjudged_box_passes_like_run_does_but_says_so(tmp_path: Path) -> None:
    entry = box_entry(box_run(tmp_path, "g", exit_code=0, cases=[case("U1-01", Verdict.SKIP)]), tmp_path)
    assert entry["status"] == "unjudged" and entry["passed"] and entry["overall"].startswith("NOT JUDGED")


def test_the_fleet_document(tmp_path: Path) -> None:
    good = box_run(tmp_path, "a", cases=[case("A4-01", P)])
    bad = box_run(tmp_path, "b", exit_code=1, cases=[case("A5-01", F)])
    doc = fleet_document([good, bad], tmp_path, fleet_file=Path("plant.toml"), jobs=2, started="2024-06-01T10:15:00",
                         duration_s=30.0, command="isight-conformance run --targets plant.toml", stopped=None)
    assert doc["format"] == "isight-fleet-1" and doc["complete"] and not doc["passed"] and doc["exit_code"] == 1
    assert doc["counts"] == {"fails": 1, "conforms": 1}
    assert doc["overall"] == "FLEET FAILS: 1 of 2 boxes do not pass"
    assert [b["name"] for b in doc["boxes"]] == ["a", "b"]
    only_good = fleet_document([good], tmp_path, fleet_file=Path("p.toml"), jobs=1, started="", duration_s=1.0,
                               command="", stopped=None)
    assert only_good["passed"] and only_good["exit_code"] == 0 and only_good["overall"].startswith("FLEET PASSES")
    stopped = fleet_document([good, box_run(tmp_path, "h", status="not run", exit_code=None)], tmp_path,
                             fleet_file=Path("p.toml"), jobs=1, started="", duration_s=1.0, command="",
                             stopped="stopped by SIGTERM")
    assert not stopped["complete"] and not stopped["passed"] and stopped["exit_code"] == 1
    assert stopped["overall"].startswith("INCOMPLETE: the run was stopped; 1 of 2 boxes finished")
    path = write_fleet_json(tmp_path / "fleet.json", stopped)
    assert json.loads(path.read_text()) == stopped
    assert not list(tmp_path.glob(".fleet.json.*"))  # written atomically: no temp file left
