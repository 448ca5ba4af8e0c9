"""conformance/harness/quiet.py: bounded time for a box that hangs after bad bytes (the hang pattern)."""

from __future__ import annotations

import socket
import threading

import pytest

from conformance.harness.client import Silence
from conformance.harness.quiet import CUT_S, HANG_CASES, Hangs, bad_kind, pattern_key
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.model.verdicts import Level
from conformance.protocol import (
    Action,
    Profile,
    ProtocolError,
    StreamDecoder,
    TransferType,
    answer,
    encode,
    pose_blocks,
    request,
)
from conformance.runtime.run_state import SessionState
from conformance.runtime.settings import SuiteSettings
from conformance.suite.case_context import CaseContext
from conformance.suite.case_judge import Inconclusive
from conformance.suite.record import CaseRecord
from tests.boxes import ScriptedBox

pytestmark = pytest.mark.timeout(60)
P = Profile(time_out_ms=1500)  # every full wait in these tests costs this
GARBAGE = b"garbage!"
BAD_INDEX = encode(request(Action.POSE, pose_blocks([(0.0,) * 6], first_index=1)))


def test_bad_bytes_are_classified_by_the_reference_framing() -> None:
    assert bad_kind(GARBAGE, P) == "not-request"
    assert bad_kind(BAD_INDEX, P) == "reject"
    assert bad_kind(encode(request(Action.NONE)), P) == "valid"
    assert bad_kind(BAD_INDEX[:14], P) == "incomplete"  # a header whose body has not come: a box may wait for it
    assert bad_kind(encode(request(Action.PROG_IDX)), P, extension=False) == "not-request"


def test_the_pattern_needs_enough_cases_and_is_withdrawn_by_one_answer() -> None:
    hangs, key = Hangs(), pattern_key("not-request", False)
    for n in range(HANG_CASES):
        assert hangs.known(key) is None and hangs.bound("not-request", False, 5.0) is None
        hangs.note(key, f"C-{n}", hung=True, probe_answered=False)
    assert hangs.known(key) == [f"C-{n}" for n in range(HANG_CASES)]
    assert hangs.bound("not-request", False, 5.0) == CUT_S
    assert hangs.bound("not-request", True, 5.0) is None  # a case judging the hang waits in full
    assert hangs.bound("reject", False, 5.0) is None  # another kind of bytes: not established
    assert hangs.known(pattern_key("not-request", True)) is None  # answered, then quiet: another pattern
    assert pattern_key("reject", True) == pattern_key("any", True) != pattern_key("not-request", True)
    hangs.note(key, "C-9", hung=False, probe_answered=True)
    assert hangs.known(key) is None  # the box resynchronised once: the silences had another cause


def test_a_legal_wait_or_a_silence_with_the_probe_answered_is_not_a_hang() -> None:
    hangs = Hangs()
    for n in range(3):
        hangs.note(pattern_key("incomplete", False), f"C-{n}", hung=False, probe_answered=False)  # a legal wait
    assert hangs.bound("incomplete", False, 5.0) is None


def hang_after_garbage(conn: socket.socket) -> None:
    """Answers requests (a malformed one 1001); after bytes that are not a frame it hangs on that connection."""
    conn.settimeout(10)
    decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
    while data := conn.recv(65536):
        for event in decoder.feed(data):
            if isinstance(event, ProtocolError) and event.header is not None and event.header.start_word == 0xFEFE:
                conn.sendall(encode(answer(Action(event.header.action), 0x1001)))  # a malformed request: refused
            elif isinstance(event, ProtocolError):
                while conn.recv(65536):
                    pass
                return
            else:
                conn.sendall(encode(answer(event.action)))


def context(state: SessionState, case_id: str, clauses: tuple[str, ...] = ("A5",),
            level: Level = Level.MUST) -> CaseContext:
    return CaseContext(state, CaseRecord(case_id, clauses, level, "t", "e"), Transcript(case_id))


def test_later_cases_on_a_known_hang_end_inconclusive_and_the_r6_cases_still_wait_in_full() -> None:
    with ScriptedBox(hang_after_garbage) as box:
        state = SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=P))
        first = [context(state, f"A5-{n}") for n in range(HANG_CASES)]
        outcomes = [ctx.send_malformed(GARBAGE) for ctx in first]
        later = context(state, "A5-9")
        with pytest.raises(Inconclusive) as cut:
            later.send_malformed(GARBAGE)
        r6 = context(state, "R6-T", ("R6",), Level.SHOULD)
        r6_outcome = r6.send_malformed(GARBAGE)
        for ctx in [*first, later, r6]:
            ctx.close_all()
    assert all(isinstance(o, Silence) for o in outcomes) and all(c.transcript.timeouts == 1 for c in first)
    assert str(cut.value.signature) == "silence:NONE" and cut.value.judged == ("R6",)
    assert "A5-0, A5-1" in cut.value.message and later.transcript.timeouts == 0  # it did not wait time_out
    assert "liveness" in {c.label for c in later.transcript.connections.values()}  # the box is alive: no R2 lost
    assert isinstance(r6_outcome, Silence) and isinstance(r6.last_probe, Silence) and r6.transcript.timeouts == 1


def test_a_box_that_answers_the_probe_is_never_cut_short() -> None:
    with ScriptedBox(hang_after_garbage) as box:
        state = SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=P))
        for n in range(HANG_CASES):
            context(state, f"A5-{n}").send_malformed(GARBAGE)
        ctx = context(state, "B3-T", ("B3",))
        outcome = ctx.send_malformed(BAD_INDEX)  # a malformed request, not garbage: answered, the probe too
        ctx.close_all()
    assert outcome.describe() == "answered box→robot POSE err=0x1001" and ctx.transcript.timeouts == 0
    assert state.hangs.known(pattern_key("reject", True)) is None
    assert state.hangs.known(pattern_key("not-request", False)) is not None


class OneAtATime:
    """A box that serves one connection at a time: the next waits in the backlog until the first closes (S4)."""

    def __init__(self) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self) -> OneAtATime:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join(5)
        self.sock.close()

    def _serve(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            with conn:
                conn.settimeout(0.2)
                decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
                while not self.stop.is_set():
                    try:
                        data = conn.recv(65536)
                    except TimeoutError:
                        continue
                    except OSError:
                        break
                    if not data:
                        break
                    conn.sendall(b"".join(encode(answer(e.action)) for e in decoder.feed(data)
                                          if not isinstance(e, ProtocolError)))


def test_a_second_connection_to_a_box_serving_one_at_a_time_is_cut_short_unless_the_case_judges_s4() -> None:
    with OneAtATime() as box:
        state = SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=P))
        state.before_case("C-0", Transcript("C-0"))
        assert state.concurrent is False
        r2 = context(state, "R2-T", ("R2",))
        first = r2.connect("abuser")
        assert first.request(encode(request(Action.NONE))).describe().startswith("answered")
        with pytest.raises(Inconclusive) as cut:
            r2.check_alive()  # a fresh connection while the case's first is open
        r2.close_all()
        s4 = context(state, "S4-T", ("S4",))
        s4.connect("stream")
        waited = s4.connect("command").request(encode(request(Action.NONE)))
        s4.close_all()
        state.stop()
    assert cut.value.judged == ("S4",) and "one connection at a time" in cut.value.message
    assert r2.transcript.timeouts == 0  # it did not wait time_out
    assert isinstance(waited, Silence) and s4.transcript.timeouts == 1  # the S4 case waits in full and judges it


def zero_then_hang(conn: socket.socket) -> None:
    """Answers malformed requests 0000 (R1 broken) and then hangs on that connection; garbage: hangs at once."""
    conn.settimeout(10)
    decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
    while data := conn.recv(65536):
        for event in decoder.feed(data):
            if isinstance(event, ProtocolError):
                if event.header is not None and event.header.start_word == 0xFEFE:
                    conn.sendall(encode(answer(Action(event.header.action))))
                while conn.recv(65536):
                    pass
                return
            conn.sendall(encode(answer(event.action)))


def test_a_0000_that_came_before_the_cut_is_judged_after_the_full_wait() -> None:
    """Cutting a wait short may turn a verdict INCONCLUSIVE, never hide the evidence of a FAIL that came."""
    with ScriptedBox(zero_then_hang) as box:
        state = SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=P))
        for n in range(HANG_CASES):
            context(state, f"B3-{n}").send_malformed(BAD_INDEX)
        assert state.hangs.known(pattern_key("reject", True)) is not None
        ctx = context(state, "B3-9", ("B3",))
        outcome = ctx.send_malformed(BAD_INDEX)  # no Inconclusive: the 0000 is judged
        ctx.close_all()
    assert outcome.describe() == "answered box→robot POSE err=0x0000"
    assert isinstance(ctx.last_probe, Silence)


def first_of_each_read(conn: socket.socket) -> None:
    """Answers only the first frame of each read (R4 broken): malformed requests 1001, garbage never."""
    conn.settimeout(10)
    decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
    while data := conn.recv(65536):
        out = []
        for event in decoder.feed(data):
            if not isinstance(event, ProtocolError):
                out.append(encode(answer(event.action)))
            elif event.header is not None and event.header.start_word == 0xFEFE:
                out.append(encode(answer(Action(event.header.action), 0x1001)))
        conn.sendall(out[0] if out else b"")


def test_a_box_dropping_the_probe_after_answering_the_bytes_is_its_own_pattern() -> None:
    """Bytes it leaves unanswered get the probe answered; that does not withdraw the pattern of bytes it answers."""
    with ScriptedBox(first_of_each_read) as box:
        state = SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=P))
        for n in range(HANG_CASES):
            context(state, f"B3-{n}").send_malformed(BAD_INDEX)
        context(state, "A5-0").send_malformed(GARBAGE)  # garbage: unanswered, the probe answered
        later = context(state, "B3-9", ("B3",))
        with pytest.raises(Inconclusive) as cut:
            later.send_malformed(BAD_INDEX)
        later.close_all()
    assert state.hangs.known(pattern_key("reject", True)) == ["B3-0", "B3-1"]
    assert "once it answered them" in cut.value.message and later.transcript.timeouts == 0
    assert cut.value.judged == ("R4", "A1")  # the probe in the segment of bytes it answered was dropped


def one_frame_per_read(conn: socket.socket) -> None:
    """Handles the first whole frame of each read and drops the rest of it (d19's kind, R4): a malformed request
    refused 1001, a frame that is not a request consumed in silence, garbage scanned past."""
    conn.settimeout(10)
    while data := conn.recv(65536):
        for event in StreamDecoder(expect=TransferType.ROBOT_TO_BOX).feed(data):  # a new one per read: the rest is lost
            if isinstance(event, ProtocolError):
                if event.header is None or event.header.start_word != 0xFEFE:
                    continue  # garbage: scanned past
                if event.header.transfer_type == TransferType.ROBOT_TO_BOX:
                    conn.sendall(encode(answer(Action(event.header.action), 0x1001)))
                break  # a whole frame handled (answered or not): the rest of the read is dropped
            conn.sendall(encode(answer(event.action)))
            break


def test_a_probe_lost_behind_whole_frames_is_one_pattern_however_the_box_phrases_it() -> None:
    """Refusals (answered) establish it; a frame that is not a request (unanswered) is then cut under R4 at once,
    and the probe answered behind garbage (not whole frames) does not withdraw it."""
    from conformance.harness.quiet import AFTER_FRAMES
    from conformance.protocol import Header, encode_raw

    not_request = encode_raw(Header(action=1, transfer_type=0), profile=P)
    with ScriptedBox(one_frame_per_read) as box:
        state = SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=P))
        for n in range(HANG_CASES):
            context(state, f"B3-{n}").send_malformed(BAD_INDEX)
        garbage = context(state, "A5-0")
        garbage.send_malformed(GARBAGE)
        later = context(state, "A5-9")
        with pytest.raises(Inconclusive) as cut:
            later.send_malformed(not_request)
        later.close_all()
        garbage.close_all()
    assert state.hangs.known(AFTER_FRAMES) == ["B3-0", "B3-1"] and not isinstance(garbage.last_probe, Silence)
    assert cut.value.judged == ("R4", "A1") and "whole frames" in cut.value.message
    assert later.transcript.timeouts == 0  # it did not wait time_out
