"""Death first (pure): a failure that left the box dead becomes R2 with the trigger's clause, and prints first."""

from __future__ import annotations

import json
from pathlib import Path

from conformance.evidence.vectors_file import load
from conformance.fuzz.death_first import DEATH_KEY, deaths_first, died, is_death, known_death
from conformance.fuzz.failure_files import Failure, write_vectors
from conformance.fuzz.failure_lines import report_lines
from conformance.fuzz.last_words import last_words
from conformance.fuzz.oracle import Finding
from conformance.fuzz.strategies import Strategies
from conformance.harness.client import Closed
from conformance.model.verdicts import Verdict
from conformance.protocol import Profile

A1 = Finding(Verdict.FAIL, "A1", "A1: the box answers well-formed requests", "closed the connection",
             "valid/answer/23/unanswered")


def test_died_is_r2_keeping_the_trigger():
    death = died(A1, Closed(True, 0.0))
    assert death.verdict is Verdict.FAIL
    assert death.clause == "R2/A1"
    assert death.key == f"{DEATH_KEY}/session/23"
    assert known_death(died(Finding(Verdict.FAIL, "R2", "R2: alive", "refused", "R2/session"), Closed(True, 0.0)),
                       {death.key})
    assert death.requirement.startswith("R2:")
    assert "closed the connection" in death.observed and "A1: the box answers" in death.observed
    assert died(Finding(Verdict.FAIL, "R2", "R2/S4: accepts", "refused", "R2/connect"), Closed(True, 0.0)).clause == "R2"


def test_deaths_print_first():
    rude = Failure(1, "stateful", ["A1"], "A1: rude", keys=["valid/answer/23/unanswered"])
    dead = Failure(2, "stateful", ["R2", "A1"], "R2: dead", keys=[f"{DEATH_KEY}/session/23"])
    frame_death = Failure(3, "death", ["R2"], "R2: dead after a frame", keys=["R2/death"])
    assert [f.number for f in deaths_first([rude, dead, frame_death])] == [2, 3, 1]
    assert is_death(dead.keys) and is_death([], "death") and not is_death(rude.keys, "stateful")
    lines = report_lines([rude, dead])
    assert lines[0].startswith("  FAIL 2 [R2, A1]")


def test_last_words_go_into_the_report_lines_and_the_vector_file(tmp_path: Path):
    s = Strategies(Profile())
    case = s.case("valid", "", s.raw(*_tolerance(s)), "tolerance ×7")
    words = last_words(1, 4242, 1, b"listening\n==7==ERROR: AddressSanitizer: heap-buffer-overflow on address 0x1\n"
                                   b"WRITE of size 35 at 0x1 thread T1\n    #1 0x5 in store_tolerances box.c:59\n")
    failure = Failure(1, "death", ["R2"], "R2: dead", [case], keys=["R2/death"], last_words=words)
    lines = report_lines([failure])
    assert lines[2] == ("       box: the box (incarnation 1, pid 4242) exit status 1: AddressSanitizer: "
                        "heap-buffer-overflow (WRITE of size 35) in store_tolerances box.c:59")
    assert lines[3].startswith("       | ==7==ERROR: AddressSanitizer")
    path = write_vectors(tmp_path / "f.json", failure, Profile(), "test")
    vectors = list(load(path))
    assert len(vectors) == 1 and "BoxLastWords" in vectors[0].flags
    raw = json.loads(path.read_text())
    assert raw["testGroups"][0]["tests"][0]["flags"] == ["BoxLastWords"]
    assert "heap-buffer-overflow" in raw["notes"]["BoxLastWords"] and "store_tolerances" in raw["notes"]["BoxLastWords"]
    assert failure.to_dict()["last_words"]["kind"] == "asan"


def _tolerance(s: Strategies):
    from conformance.protocol import Action, BlockType, Header

    header = Header(action=Action.TOLERANCE, block_type=BlockType.TOLERANCE, block_count=7, block_length=5)
    return header, s.blocks(BlockType.TOLERANCE, 7, bytes(4))
