"""What a finished case becomes (conformance/engine/results.py): its verdict, evidence and result."""

from __future__ import annotations

from pathlib import Path

import pytest

from conformance.engine.results import (
    QUOTED_BYTES,
    attach_evidence,
    bounded_hex,
    max_open,
    result_of,
    safe_name,
)
from conformance.harness.client import Malformed
from conformance.harness.target import Unreachable
from conformance.harness.transcript import Endpoint, Kind, Transcript
from conformance.model.signature import Sig, Signature
from conformance.model.verdicts import Level, Verdict, broken_verdict
from conformance.protocol import Action, ProtocolError, StreamDecoder, TransferType, answer, encode, request
from conformance.runtime.run_state import SessionState
from conformance.runtime.settings import SuiteSettings
from conformance.suite.case_context import CaseContext
from conformance.suite.case_judge import CaseVerdict, Inconclusive, Skip, answered, check, fail
from conformance.suite.record import CaseRecord, record

POSE_CASE = record("S3-01", ["S3"], Level.MUST, "Poses before CycleOn are answered 0000", "answered POSE 0000")
BOX = Endpoint("127.0.0.1", 9000)


def conn(transcript: Transcript, port: int, transport: str = "tcp") -> int:
    return transcript.open(transport, Endpoint("127.0.0.1", port), BOX, f"conn {port}").conn


def context(info: CaseRecord = POSE_CASE, tmp_path: Path | None = None) -> CaseContext:
    ctx = CaseContext(SessionState(SuiteSettings()), info, Transcript(case_id=info.id))
    if tmp_path is not None:
        ctx.pcap = tmp_path / "S3-01.pcapng"
    return ctx


def version_0100_answer() -> Malformed:
    raw = bytearray(encode(answer(Action.POSE)))
    raw[2:4] = b"\x01\x00"
    decoder = StreamDecoder(expect=TransferType.BOX_TO_ROBOT)
    decoder.receive_data(bytes(raw))
    event = decoder.next_event()
    assert isinstance(event, ProtocolError)
    return Malformed(event, 0.001)


def verdict_of(outcome: Malformed) -> CaseVerdict:
    with pytest.raises(CaseVerdict) as caught:
        check(outcome, answered(Action.POSE, [0]), Level.MUST, "S3: poses before CycleOn are answered 0000",
              sent=encode(request(Action.POSE)))
    return caught.value


# -- bounded_hex, safe_name ----------------------------------------------------------------------------
def test_bounded_hex_quotes_everything_up_to_the_bound() -> None:
    assert bounded_hex(b"") == ""
    assert bounded_hex(b"\xfe\xfe\x00\x01") == "fe fe 00 01"
    whole = bytes(range(256)) * (QUOTED_BYTES // 256)
    assert len(whole) == QUOTED_BYTES
    assert bounded_hex(whole) == whole.hex(" ")


def test_bounded_hex_cuts_a_flood_and_says_how_much_there_was() -> None:
    flood = b"\xab" * (10 * QUOTED_BYTES + 1)
    text = bounded_hex(flood)
    quoted, _, rest = text.partition(" … ")
    assert quoted == (b"\xab" * QUOTED_BYTES).hex(" ")
    assert rest == f"({len(flood)} bytes in all)"
    assert len(text) < 3 * QUOTED_BYTES + 60
    assert bounded_hex(b"\x00" * (QUOTED_BYTES + 1)).endswith(f"({QUOTED_BYTES + 1} bytes in all)")


def test_safe_name_keeps_a_case_id_readable_and_path_free() -> None:
    assert safe_name("B3-02[gap-pose]") == "B3-02_gap-pose_"
    assert safe_name("SEQ-USER[../../etc/passwd]") == "SEQ-USER_.._.._etc_passwd_"
    assert "/" not in safe_name("a/b\\c d") and safe_name("T1-00.x_y") == "T1-00.x_y"


# -- max_open -----------------------------------------------------------------------------------------
def test_max_open_counts_connections_held_at_once() -> None:
    t = Transcript()
    assert max_open(t) == 0
    command, stream = conn(t, 50001), conn(t, 50002)
    t.add(command, Kind.CONNECT)
    t.add(command, Kind.SEND, b"\xfe\xfe")
    t.add(stream, Kind.CONNECT)  # S4: the stream opens while the command connection is open
    t.add(command, Kind.CLOSE)
    t.add(stream, Kind.PEER_CLOSE)
    later = conn(t, 50003)
    t.add(later, Kind.CONNECT)  # the most at once is what counts, not the last count
    t.add(later, Kind.CLOSE)
    assert max_open(t) == 2


def test_connections_one_after_another_are_one_at_a_time() -> None:
    t = Transcript()
    for port in range(50001, 50011):
        c = conn(t, port)
        t.add(c, Kind.CONNECT)
        t.add(c, Kind.RECV, b"\xfe\xfe")
        t.add(c, Kind.CLOSE)
    assert max_open(t) == 1


@pytest.mark.parametrize("end", [Kind.CLOSE, Kind.ABORT, Kind.PEER_CLOSE, Kind.PEER_RESET])
def test_every_way_a_connection_ends_frees_it(end: str) -> None:
    t = Transcript()
    first, second = conn(t, 50001), conn(t, 50002)
    t.add(first, Kind.CONNECT)
    t.add(first, end)
    t.add(second, Kind.CONNECT)
    assert max_open(t) == 1


def test_failed_connects_udp_channels_and_notes_are_not_connections_held() -> None:
    t = Transcript()
    tcp, refused, udp = conn(t, 50001), conn(t, 50002), conn(t, 50003, "udp")
    t.add(tcp, Kind.CONNECT)
    t.add(refused, Kind.CONNECT_FAILED, note="connection refused")
    t.add(udp, Kind.CONNECT)  # a bound UDP socket
    t.note("a step marker")
    t.add(99, Kind.CONNECT)  # an event for no known connection
    assert max_open(t) == 1


def test_hundreds_of_idle_connections_are_counted() -> None:
    t = Transcript()
    held = [conn(t, 40000 + n) for n in range(300)]
    for c in held:
        t.add(c, Kind.CONNECT)
    probe = conn(t, 39999)
    t.add(probe, Kind.CONNECT)
    assert max_open(t) == 301


# -- result_of: verdicts --------------------------------------------------------------------------------
def test_a_case_that_returns_passes_with_no_finding() -> None:
    result = result_of(POSE_CASE, None, None, 0.25)
    assert (result.verdict, result.message, result.requirement) == (Verdict.PASS, "", "")
    assert (result.judged, result.signature, result.root_cause) == ((), None, None)
    assert (result.clauses, result.expected, result.duration_s) == (("S3",), "answered POSE 0000", 0.25)
    assert result.sent_hex == "" and result.details == {} and result.pcap is None


def test_a_malformed_answer_fails_on_its_format_and_names_the_clause_it_judged() -> None:
    exc = verdict_of(version_0100_answer())
    result = result_of(POSE_CASE, None, exc, 0.1)
    assert result.verdict is Verdict.FAIL
    assert result.judged == ("F2",)
    assert result.clauses == ("S3", "F2")  # what it judged joins the clauses the case names
    assert str(result.signature) == "answer:F2:version=0100"
    assert result.requirement == "F2: the box's answers are conforming frames"
    assert result.message.startswith("F2: the box's answer is not a conforming frame")
    assert result.expected == "answered POSE with error 0x0000 (OK)"
    assert result.received_hex == "fe fe 01 00 10 23 00 00 00 00 00 00 00 00"
    assert result.sent_hex == encode(request(Action.POSE)).hex(" ")


def test_a_clause_named_twice_is_listed_once() -> None:
    info = record("F2-01", ["F2"], Level.MUST, "Answers carry version 00 01", "00 01")
    assert result_of(info, None, verdict_of(version_0100_answer()), 0.1).clauses == ("F2",)


@pytest.mark.parametrize("level", [Level.MUST, Level.SHOULD])
def test_a_finding_without_clause_or_signature_is_the_case_own(level: Level) -> None:
    info = record("R4-01", ["R4", "A1"], level, "Ten frames in one segment are each answered", "ten answers")
    exc = fail(level, "each frame of the segment is answered", "ten answers", "one answer")
    result = result_of(info, None, exc, 0.1)
    assert result.verdict is broken_verdict(level)
    assert result.judged == ("R4", "A1")  # the case's clauses
    assert result.signature == Signature.own("R4-01")  # groups with nothing else
    assert result.requirement == "each frame of the segment is answered"


def test_an_inconclusive_verdict_keeps_the_signature_that_explains_it() -> None:
    refused = Inconclusive("box unreachable since case B1-02 (a fresh connection stayed silent)",
                           signature=Signature.unreachable("B1-02"))
    result = result_of(POSE_CASE, None, refused, 0.0)
    assert (result.verdict, result.signature, result.judged) == (Verdict.INCONCLUSIVE, Signature.unreachable("B1-02"), ())
    assert result.requirement == POSE_CASE.words == "S3 (MUST): Poses before CycleOn are answered 0000"
    unexplained = result_of(POSE_CASE, None, Inconclusive("the box is not ready (CycleOn answered 0001)"), 0.0)
    assert unexplained.signature is None  # not a FAIL: no case signature of its own
    late = Inconclusive("CYCLE_ON is not answered within time_out (cases S2-01, A3-02)", signature=Signature(Sig.SILENCE, "CYCLE_ON"))
    assert result_of(POSE_CASE, None, late, 0.0).signature == Signature(Sig.SILENCE, "CYCLE_ON")


def test_an_unreachable_box_is_inconclusive_with_what_was_sent() -> None:
    ctx = context()
    ctx.last_sent = b"\xfe\xfe\x00\x01"
    result = result_of(POSE_CASE, ctx, Unreachable("127.0.0.1:9: connection refused"), 0.0)
    assert result.verdict is Verdict.INCONCLUSIVE
    assert result.message == "box unreachable: 127.0.0.1:9: connection refused"
    assert result.sent_hex == "fe fe 00 01" and result.requirement == POSE_CASE.words
    assert result.judged == () and result.signature is None


def test_skips() -> None:
    result = result_of(POSE_CASE, None, Skip("extension E not implemented by the box"), 0.0)
    assert (result.verdict, result.message) == (Verdict.SKIP, "extension E not implemented by the box")
    skipped = pytest.skip.Exception("no --udp-target given")
    result = result_of(POSE_CASE, None, skipped, 0.0, skipped=True)
    assert (result.verdict, result.message) == (Verdict.SKIP, "no --udp-target given")


@pytest.mark.parametrize(("level", "verdict"), [(Level.MUST, Verdict.FAIL), (Level.SHOULD, Verdict.NON_STRICT),
                                                (Level.MAY, Verdict.INFORMATIONAL)])
def test_a_failed_assert_is_the_level_verdict(level: Level, verdict: Verdict) -> None:
    info = record("B3-02", ["B3", "A3", "R1"], level, "Index errors are parse errors", "not 0000")
    exc = AssertionError("A3/R1: a parse error was answered 0000\nassert 0 != 0")
    result = result_of(info, None, exc, 0.1)
    assert result.verdict is verdict
    assert result.message == "A3/R1: a parse error was answered 0000"  # the first line only
    # an assert names no clause: the case's own (nothing is read out of its words)
    assert result.judged == (("B3", "A3", "R1") if verdict in (Verdict.FAIL, Verdict.NON_STRICT) else ())


def test_a_bare_assert_judges_the_case_clauses() -> None:
    result = result_of(POSE_CASE, None, AssertionError(), 0.1)
    assert (result.verdict, result.message, result.judged) == (Verdict.FAIL, "assertion failed", ("S3",))
    assert result.signature == Signature.own("S3-01")


def test_any_other_exception_is_the_suite_own_error() -> None:
    def broken_case() -> None:
        raise ValueError("boom")

    with pytest.raises(ValueError) as caught:
        broken_case()
    result = result_of(POSE_CASE, None, caught.value, 0.1)
    assert result.verdict is Verdict.ERROR
    assert result.message == "suite error: ValueError: boom"
    assert "broken_case" in result.observed and "ValueError: boom" in result.observed
    assert (result.judged, result.signature) == ((), None)  # never a finding about the box


def test_a_flood_is_quoted_bounded() -> None:
    flood = b"\x9c\x41" * (4 * QUOTED_BYTES)
    exc = fail(Level.MUST, "R5: resources are bounded", "answers", "a flood", received=flood, signature=Signature(Sig.CLOSED, "NONE"))
    result = result_of(POSE_CASE, None, exc, 0.1)
    assert result.received_hex == bounded_hex(flood)
    assert result.received_hex.endswith(f"({len(flood)} bytes in all)")


# -- result_of: what the case's context adds ---------------------------------------------------------
def test_the_context_adds_wire_latencies_details_and_pcap(tmp_path: Path) -> None:
    ctx = context(tmp_path=tmp_path)
    c = conn(ctx.transcript, 50001)
    ctx.transcript.add(c, Kind.CONNECT)
    ctx.transcript.add(c, Kind.SEND, encode(request(Action.NONE)))
    ctx.transcript.add(c, Kind.RECV, encode(answer(Action.NONE)))
    ctx.latencies_ms.append(1.5)
    ctx.details["framing"] = "resync"
    result = result_of(POSE_CASE, ctx, None, 0.1)
    assert result.verdict is Verdict.PASS
    assert result.details == {"framing": "resync", "max_open_connections": 1}
    assert "max_open_connections" not in ctx.details  # the case's own dict is not changed
    assert result.latencies_ms == [1.5] and result.latencies_ms is not ctx.latencies_ms
    assert result.pcap == str(tmp_path / "S3-01.pcapng")
    assert [w.direction for w in result.wire] == ["·", "→", "←"]
    assert result.wire[1].hex == encode(request(Action.NONE)).hex(" ")


def test_an_informational_case_reports_what_it_recorded() -> None:
    ctx = context()
    ctx.inform("the box expects first index 01")
    ctx.last_sent = b"\xfe\xfe"
    result = result_of(POSE_CASE, ctx, None, 0.1)
    assert result.verdict is Verdict.INFORMATIONAL
    assert result.message == result.observed == "the box expects first index 01"
    assert result.sent_hex == "fe fe" and result.requirement == POSE_CASE.words
    assert result.judged == () and result.signature is None


def test_the_verdict_own_bytes_win_over_the_last_sent() -> None:
    ctx = context()
    ctx.last_sent = b"\x00\x00"
    result = result_of(POSE_CASE, ctx, verdict_of(version_0100_answer()), 0.1)
    assert result.sent_hex == encode(request(Action.POSE)).hex(" ")


# -- attach_evidence -----------------------------------------------------------------------------------
def test_evidence_is_a_pcap_per_case_only_when_asked_for(tmp_path: Path) -> None:
    t = Transcript(case_id="B3-02[gap-pose]")
    assert attach_evidence(t, SuiteSettings(), "B3-02[gap-pose]") is None  # no --pcap-dir
    off = SuiteSettings(pcap_dir=tmp_path / "off", capture="off")
    assert attach_evidence(t, off, "B3-02[gap-pose]") is None and not (tmp_path / "off").exists()
    path = attach_evidence(t, SuiteSettings(pcap_dir=tmp_path / "pcaps"), "B3-02[gap-pose]")
    assert path == tmp_path / "pcaps" / "B3-02_gap-pose_.pcapng"
    assert len(t.listeners) == 1
    c = conn(t, 50001)
    t.add(c, Kind.CONNECT)
    t.add(c, Kind.SEND, encode(request(Action.NONE)))
    t.close()
    assert path.read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"  # a pcapng section header block
    assert encode(request(Action.NONE)) in path.read_bytes()
