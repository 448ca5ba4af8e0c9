"""Transport root causes (engine/transport_causes) and the UDP family's pure parts (diagnose/udp_family, udp_titles):
every F6/F7/R7 FAIL and UDP fuzz finding belongs to one root cause; CRCs are named as the catalogue writes them."""

from __future__ import annotations

from conformance.diagnose import udp_family, udp_titles
from conformance.engine.rootcause import find_root_causes
from conformance.engine.transport_causes import transport_causes, udp_fuzz
from conformance.model.verdicts import CaseResult, Level, Verdict
from conformance.protocol import crc_function


def result(case_id: str, verdict: Verdict = Verdict.FAIL, **details: object) -> CaseResult:
    out = CaseResult(case_id, case_id, ("F7",), Level.MUST, verdict, "seen")
    out.details.update(details)
    return out


def udp_failure(transport: str) -> dict[str, object]:
    return {"failures": [{"cases": [{"transport": transport, "hex": "fefe"}]}]}


def test_every_failing_udp_case_and_udp_fuzz_finding_is_one_root_cause() -> None:
    cases = [result("F7-01"), result("R7-01[two-frames]"), result("F7-02", Verdict.PASS),
             result("FUZZ-01", fuzz=udp_failure("udp")), result("FUZZ-02", fuzz=udp_failure("tcp"))]
    causes = find_root_causes(cases)
    udp = [c for c in causes if c.kind == "udp"]
    assert len(udp) == 1 and udp[0].cases == ["F7-01", "R7-01[two-frames]", "FUZZ-01"]
    assert udp[0].level is Level.MUST and "F7" in udp[0].clauses
    assert cases[0].root_cause == udp[0].id and cases[2].root_cause is None


def test_a_single_failing_f6_case_gets_a_root_cause() -> None:
    [(cause, members)] = transport_causes([result("F6-01"), result("F6-02", Verdict.PASS)])
    assert cause.kind == "tcp-check" and cause.clauses == ("F6",) and [m.id for m in members] == ["F6-01"]


def test_a_non_strict_udp_case_alone_is_a_should_root_cause() -> None:
    [cause] = find_root_causes([result("R7-01[wrong-crc]", Verdict.NON_STRICT)])
    assert cause.kind == "udp" and cause.level is Level.SHOULD


def test_no_udp_failure_no_udp_root_cause() -> None:
    assert transport_causes([result("F7-01", Verdict.PASS), result("FUZZ-01", fuzz=udp_failure("tcp"))]) == []
    assert not udp_fuzz(result("FUZZ-01", fuzz={"failures": []}))


def test_crc_names_as_the_crc_catalogue_writes_them() -> None:
    assert udp_titles.crc_name("crc-ccitt-false") == "CRC-16/CCITT-FALSE"
    assert udp_titles.crc_name("modbus") == "CRC-16/MODBUS"
    assert udp_titles.crc_name("crc-16") == "CRC-16/ARC"
    assert udp_titles.crc_name("crc-16-maxim") == "CRC-16/MAXIM"


def test_the_crc_candidates_try_every_other_algorithm_and_order_common_ones_first() -> None:
    pairs = udp_family.candidates("modbus", "big")
    assert ("modbus", "big") not in pairs and pairs[0] == ("modbus", "little")
    assert pairs[1:3] == [("crc-ccitt-false", "big"), ("crc-ccitt-false", "little")]
    assert len(pairs) == len(set(pairs))


def test_crc_matches_finds_the_algorithm_and_byte_order() -> None:
    body = bytes.fromhex("fefe00011000000000000000")
    check = crc_function("crc-ccitt-false")(body).to_bytes(2, "little")
    assert ("crc-ccitt-false", "little") in udp_family.crc_matches(body, check)


def test_titles_name_the_mechanism_and_the_flag() -> None:
    title = udp_titles.of("udp-crc-algorithm", {"crc": "crc-ccitt-false", "order": "big", "profile": "modbus",
                                               "signs": True, "order_differs": False})
    assert title.startswith("Signs and checks UDP frames with CRC-16/CCITT-FALSE, not CRC-16/MODBUS")
    assert "`--crc crc-ccitt-false`" in title
    title = udp_titles.of("udp-crc-coverage", {"cover": (0, 11)})
    assert "CRC over the 12-byte header only, not over the blocks" in title and "bytes 0..11" in title
    assert "over the blocks only, not over the header" in udp_titles.of("udp-crc-coverage", {"cover": (12, 36)})
    assert "without its start word (bytes 2..36)" in udp_titles.of("udp-crc-coverage", {"cover": (2, 36)})
    title = udp_titles.of("udp-crc-one-byte", {"ignored": 2, "checked": 1, "at": 13})
    assert "Checks only one byte of the UDP CRC" in title and "byte 2 of 2 (frame byte 13)" in title
    title = udp_titles.of("udp-crc-unchecked", {"check": "5a a5"})
    assert "CRC not checked" in title and "5a a5" in title and "R7" in title
    title = udp_titles.of("tcp-check-field", {"check": "a3 f5", "matches": [("modbus", "big")]})
    assert "a3 f5" in title and "F6" in title


def test_a_box_stall_is_its_own_root_cause_and_comes_first() -> None:
    from conformance.engine.box_events import stall_causes

    stall = {"after": "fe fe 00 00 …", "example": 121, "writes": 138, "lasted_s": 6.02,
             "affected": "the connection in flight and a fresh connection"}
    fuzz = result("FUZZ-01", box_stall=[stall])
    causes = find_root_causes([fuzz, result("F7-01")])
    assert causes[0].kind == "box-stall" and causes[0].clauses == ("T1", "S4") and causes[0].cases == ["FUZZ-01"]
    assert "stalled for about 6.0 s" in causes[0].title and "write 138" in causes[0].title
    assert fuzz.root_cause == causes[0].id
    assert stall_causes([result("FUZZ-01", Verdict.PASS, box_stall=[stall])]) == []


def test_a_catalogue_case_that_met_a_stall_is_explained_by_it_not_by_its_input() -> None:
    from conformance.runtime.box_stall import STALL, Stall, verdict

    stall = Stall("B5-01", "fe fe 00 01", 197, 5.9, "the case's connection and a fresh connection were held")
    raised = verdict(stall, b"\xfe\xfe")
    case = result("B5-01")
    case.signature, case.observed, case.judged = raised.signature, raised.observed, raised.judged
    [cause] = find_root_causes([case])
    assert raised.signature == STALL and cause.kind == "box-stall" and cause.clauses == ("T1", "S4")
    assert cause.title.startswith("The whole box stalled for about 5.9 s, once: case B5-01 met it")
    assert "write 197" in cause.title and case.root_cause == cause.id


def test_a_fresh_connection_answered_late_right_after_a_silence_is_a_stall_and_a_prompt_one_is_not() -> None:
    import time

    from conformance.harness.client import Answer, Silence
    from conformance.harness.transcript import Kind, Transcript
    from conformance.protocol import Action, answer
    from conformance.runtime.box_stall import held

    tr = Transcript("A1-01")
    tr.add(1, Kind.SEND, bytes.fromhex("fefe00010100000000000000" "0000"), "NONE")
    ended = time.time()
    tr.timeouts = 1
    late, prompt = Answer(answer(Action.NONE), 1.0, b""), Answer(answer(Action.NONE), 0.002, b"")
    stall = held(tr, late, 0.001, 5.0, "A1-01", b"", 16, ended)
    assert stall is not None and stall.case_id == "A1-01" and stall.after.startswith("fe fe 00 01 01 00")
    assert "answered only after 1000 ms" in stall.affected and stall.writes == 16
    assert held(tr, prompt, 0.001, 5.0, "A1-01", b"", 16, ended) is None
    assert held(tr, late, 0.2, 5.0, "A1-01", b"", 16, ended) is None  # a box this slow anyway: not held
    assert held(tr, Silence(5.0), 0.001, 5.0, "A1-01", b"", 16, ended) is None  # silent: a death, judged elsewhere
    tr.timeouts = 0
    assert held(tr, late, 0.001, 5.0, "A1-01", b"", 16, ended) is None  # the case itself was answered in time


def test_a_short_datagram_completed_from_the_previous_one_is_titled_with_its_length() -> None:
    title = udp_titles.of("udp-short-completed", {"missing": 3, "size": 36, "frame": 39})
    assert "3 bytes short" in title and "36 of 39" in title and "previous datagram" in title
    assert "length" in title and "R7" in title
    assert udp_family.ORDER.index("udp-trailing") < udp_family.ORDER.index("udp-short-completed")
    assert udp_family._CLAUSES["udp-short-completed"] == ("R7", "F7")
