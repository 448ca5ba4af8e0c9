"""conformance/harness/exchange.py and liveness.py: the one probed-exchange engine the catalogue,
the fuzzer and replay share (probe choice, collect, settle window, attribution, liveness)."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

import pytest

from conformance.fuzz.executor import Executor
from conformance.fuzz.strategies import Strategies
from conformance.harness.client import Answer, Closed, Malformed, Silence, TcpConnection
from conformance.harness.exchange import (
    PROBE_ACTIONS,
    Settle,
    attribute,
    choose_probe,
    collect,
    probe_request,
)
from conformance.harness.liveness import check_alive, responsive, unreachable_outcome
from conformance.harness.target import Refused, Target, Unreachable
from conformance.harness.transcript import Transcript
from conformance.model.verdicts import Level, Verdict
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
from conformance.suite.record import CaseRecord
from tests.boxes import ScriptedBox, answering

pytestmark = pytest.mark.timeout(60)
P = Profile(time_out_ms=2000)
NONE = encode(request(Action.NONE))
POSE = encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
TOLERANCE = encode(probe_request(Action.TOLERANCE, P))
GARBAGE = b"garbage!"


# -- the probe -----------------------------------------------------------------------------------------------


def test_the_probe_avoids_every_action_a_legal_framing_finds_in_the_bytes_and_the_case_s_own() -> None:
    assert choose_probe(GARBAGE) is Action.NONE
    assert choose_probe(b"\xfe" + NONE) is Action.POSE  # FE FE FE 00 01 ...: a NONE one byte in (R6 resync)
    assert choose_probe(NONE + POSE) is Action.TOLERANCE
    assert choose_probe(NONE + POSE + TOLERANCE) is Action.REGISTER_POSE
    assert choose_probe(GARBAGE, used={Action.NONE}) is Action.POSE  # a request of the case, not in the bytes


def test_no_probe_when_the_bytes_hold_every_probe_action() -> None:
    """The catalogue fell back to TOLERANCE and the fuzzer to NONE even when the bytes held a frame with it:
    the first answer with that action could then be the embedded frame's, ending the wait before the probe's."""
    every = b"".join(encode(probe_request(a, P)) for a in PROBE_ACTIONS)
    assert choose_probe(every) is None
    assert choose_probe(GARBAGE, used=set(PROBE_ACTIONS)) is None


def test_every_probe_is_a_valid_request_in_the_profile() -> None:
    for first_index in (0, 1):
        profile = Profile(first_index=first_index)
        for action in PROBE_ACTIONS:
            frame = probe_request(action, profile)
            events = StreamDecoder(profile, TransferType.ROBOT_TO_BOX).feed(encode(frame, profile))
            assert len(events) == 1 and not isinstance(events[0], ProtocolError), (first_index, action)
            assert events[0].action is action


# -- the settle window -----------------------------------------------------------------------------------------


def test_the_settle_window_follows_the_box_s_pace_within_its_bounds() -> None:
    s = Settle(floor_s=0.005, cap_s=0.05, pace=4.0)
    assert s.window(0.0001, ambiguous=False) == 0.005  # a fast box pays the floor
    assert s.window(0.004, ambiguous=False) == pytest.approx(0.016)
    assert s.window(2.0, ambiguous=False) == 0.05  # bounded
    assert s.window(0.0001, ambiguous=True) == 0.05  # an error answer with the probe's action: the whole window
    assert Settle.fixed(0.05).window(0.0, ambiguous=False) == 0.05
    quick = Settle(0.0, 0.05, 0.0)  # the fuzzer outside confirmation: only what has arrived
    assert quick.window(1.0, ambiguous=False) == 0.0 and quick.window(1.0, ambiguous=True) == 0.05


# -- collect and attribute against scripted boxes ------------------------------------------------------------


def refuse_bad_bytes(then: Callable[[socket.socket, bytes], None]) -> Callable[[socket.socket], None]:
    """A box that refuses bytes that are not a request with action 00 and error FFFF (A5 allows a refusal with
    either action), then does ``then(conn, answers to the requests that followed)``."""

    def handler(conn: socket.socket) -> None:
        conn.settimeout(5)
        decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
        while data := conn.recv(65536):
            events = decoder.feed(data)
            if any(isinstance(e, ProtocolError) for e in events):
                rest = b"".join(encode(answer(e.action)) for e in events if not isinstance(e, ProtocolError))
                conn.sendall(encode(answer(Action.NONE, 0xFFFF)))
                then(conn, rest)
                return
            conn.sendall(b"".join(encode(answer(e.action)) for e in events if not isinstance(e, ProtocolError)))

    return handler


def refusal_code(outcome: object) -> int | None:
    header = outcome.error.header if isinstance(outcome, Malformed) else None
    return header.error_code if header is not None else None


def close_after(conn: socket.socket, rest: bytes) -> None:
    conn.close()  # R6(c): close after bytes that are not a request (the probe is never read)


def answer_in_two_writes(conn: socket.socket, rest: bytes) -> None:
    """The probe's answer begun at once and finished 0.3 s later (a box writing in pieces, latency legal)."""
    conn.sendall(rest[:1])
    time.sleep(0.3)
    conn.sendall(rest[1:])
    conn.settimeout(5)
    while conn.recv(65536):
        pass


def exchange(port: int, data: bytes, settle: Settle) -> tuple[TcpConnection, Action, object]:
    probe = choose_probe(data)
    assert probe is not None
    conn = TcpConnection(Transcript("T"), Target("127.0.0.1", port), P, "t").connect()
    start = time.monotonic()
    conn.send(data + encode(probe_request(probe, P)))
    return conn, probe, collect(conn, probe, start, settle)


def test_a_refusal_with_the_probe_s_action_then_a_close_is_legal() -> None:
    """The executor took the refusal (NONE, FFFF) for the probe's wrong answer and judged the end ANSWERED:
    a NON-STRICT R6 for a box that chose R6(c). The close within the window makes the end CLOSED."""
    with ScriptedBox(refuse_bad_bytes(close_after)) as box:
        conn, probe, got = exchange(box.port, GARBAGE, Settle())
        conn.close()
        ex = Executor(Target("127.0.0.1", box.port), P, Transcript("T"))
        result = ex.run(Strategies(P, extension=True, udp=False).case("t", "F1", GARBAGE, "t"))
        ex.close()
    assert got.close is not None and not got.usable and got.kind.value == "closed"
    explanation = attribute(GARBAGE + encode(probe_request(probe, P)), got, P, probe_at=len(GARBAGE))
    assert explanation.findings == [] and explanation.answers_within(0, len(GARBAGE)) == [0]
    assert result.verdict is Verdict.PASS and isinstance(result.end, Closed), result.judgement.describe()


def test_an_answer_begun_when_the_window_closes_is_read_to_its_end() -> None:
    """After a refusal carrying the probe's action, the catalogue read on 5 ms: the probe's 0000 answer,
    begun but finished later, was missed and the refusal taken for the probe's answer (a false A4)."""
    with ScriptedBox(refuse_bad_bytes(answer_in_two_writes)) as box:
        conn, probe, got = exchange(box.port, GARBAGE, Settle())
        conn.close()
    assert isinstance(got.end, Answer) and got.end.frame.action is probe and got.end.frame.error_code == 0
    assert [refusal_code(o) for o in got.outcomes] == [0xFFFF]
    explanation = attribute(GARBAGE + encode(probe_request(probe, P)), got, P, probe_at=len(GARBAGE))
    assert explanation.findings == []


def answer_late(conn: socket.socket, rest: bytes) -> None:
    """The probe's answer 0.3 s after the refusal: past the settle window, well within time_out (T1)."""
    time.sleep(0.3)
    conn.sendall(rest)
    conn.settimeout(5)
    while conn.recv(65536):
        pass


def test_the_probe_s_answer_may_trail_a_refusal_with_its_action_by_more_than_the_window() -> None:
    """A box refusing bytes under action 00 (A5) and answering the NONE probe 0.3 s later: the refusal was
    taken for the probe's answer, and the probe's 0000 read as the answer to the next request (a false A1 in
    fuzz campaigns against tests/impls/selectbox)."""
    with ScriptedBox(refuse_bad_bytes(answer_late)) as box:
        conn, probe, got = exchange(box.port, GARBAGE, Settle())
        conn.close()
    assert isinstance(got.end, Answer) and got.end.frame.action is probe and got.end.frame.error_code == 0
    assert [refusal_code(o) for o in got.outcomes] == [0xFFFF] and got.close is None
    explanation = attribute(GARBAGE + encode(probe_request(probe, P)), got, P, probe_at=len(GARBAGE))
    assert explanation.findings == []


def test_send_malformed_uses_the_engine_and_attributes_the_refusal_to_the_bytes() -> None:
    with ScriptedBox(refuse_bad_bytes(answer_in_two_writes)) as box:
        state = SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=P))
        ctx = CaseContext(state, CaseRecord("A5-T", ("A5",), Level.MUST, "t", "e"), Transcript("A5-T"))
        outcome = ctx.send_malformed(GARBAGE)
        ctx.close_all()
    assert refusal_code(outcome) == 0xFFFF  # the bytes' refusal (NONE with an error: A4 reads it as malformed)
    assert isinstance(ctx.last_probe, Answer) and ctx.last_probe.frame.error_code == 0  # the probe's answer
    assert ctx.last_explanation is not None and ctx.last_explanation.findings == []


def test_late_extras_within_the_window_are_answers_nobody_asked_for() -> None:
    with ScriptedBox(answering(lambda f: encode(answer(f.action)) * 2)) as box:
        conn, probe, got = exchange(box.port, POSE, Settle.fixed(0.2))
        conn.close()
    assert isinstance(got.end, Answer) and got.end.frame.action is probe
    explanation = attribute(POSE + encode(probe_request(probe, P)), got, P, probe_at=len(POSE))
    assert {f.clause for f in explanation.findings} == {"A1"} and explanation.unasked


# -- liveness -------------------------------------------------------------------------------------------------


def test_a_refused_connection_is_typed_and_reads_as_a_reset() -> None:
    with socket.socket() as holder:  # bound, not listening: connections are refused
        holder.bind(("127.0.0.1", 0))
        port = holder.getsockname()[1]
        with pytest.raises(Refused):
            TcpConnection(Transcript("T"), Target("127.0.0.1", port), P).connect()
        outcome = check_alive(Transcript("T"), Target("127.0.0.1", port), P)
    assert isinstance(outcome, Closed) and outcome.reset and not responsive(outcome)
    assert isinstance(unreachable_outcome(Unreachable("timed out"), 2.0), Silence)


def test_a_live_box_answers_the_liveness_check() -> None:
    with ScriptedBox(answering()) as box:
        outcome = check_alive(Transcript("T"), Target("127.0.0.1", box.port), P)
    assert isinstance(outcome, Answer) and responsive(outcome)
    assert not responsive(Malformed(ProtocolError("no header", raw=b"no"), 0.0))
