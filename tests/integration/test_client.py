"""conformance.harness.client: every box behaviour becomes an outcome value, all recorded."""

from __future__ import annotations

import pytest

from conformance.harness.client import Answer, Closed, Malformed, Silence, TcpConnection, UdpChannel
from conformance.harness.target import Target, Unreachable
from conformance.harness.transcript import Kind, Transcript
from conformance.protocol import Action, ErrorCode, Profile, answer, encode, request
from tests.boxes import ScriptedBox, answering, close_at_once, garbage, reset_at_once, silent

FAST = Profile(time_out_ms=400)


def _conn(box: ScriptedBox, transcript: Transcript | None = None) -> TcpConnection:
    return TcpConnection(transcript or Transcript("t"), Target("127.0.0.1", box.port), FAST, "command").connect()


def test_answer_is_decoded_and_recorded() -> None:
    with ScriptedBox(answering()) as box:
        t = Transcript("t")
        conn = _conn(box, t)
        outcome = conn.request(request(Action.CYCLE_ON), "CycleOn")
        conn.close()
    assert isinstance(outcome, Answer) and outcome.frame == answer(Action.CYCLE_ON)
    assert outcome.raw == encode(answer(Action.CYCLE_ON)) and outcome.latency_s >= 0
    kinds = [e.kind for e in t.events]
    assert kinds[:3] == [Kind.CONNECT, Kind.SEND, Kind.RECV] and kinds[-1] == Kind.CLOSE
    assert t.sent() == encode(request(Action.CYCLE_ON)) and t.received() == outcome.raw
    assert t.events[1].note == "CycleOn"


def test_error_answers_keep_their_code() -> None:
    with ScriptedBox(answering(lambda f: encode(answer(f.action, ErrorCode.NOT_READY)))) as box:
        outcome = _conn(box).request(request(Action.CYCLE_ON))
    assert isinstance(outcome, Answer) and outcome.frame.error_code == ErrorCode.NOT_READY


def test_silence_until_the_deadline() -> None:
    with ScriptedBox(silent) as box:
        outcome = _conn(box).request(request(Action.NONE), timeout_s=0.1)
    assert isinstance(outcome, Silence) and outcome.waited_s >= 0.1


def test_garbage_is_malformed_with_its_clause() -> None:
    with ScriptedBox(garbage) as box:
        outcome = _conn(box).request(request(Action.NONE))
    assert isinstance(outcome, Malformed) and outcome.error.clause == "F1"
    assert outcome.error.raw.startswith(b"hello")


def test_close_and_reset_are_outcomes_not_exceptions() -> None:
    with ScriptedBox(close_at_once) as box:
        conn = _conn(box)
        outcome = conn.request(request(Action.NONE))
        assert isinstance(outcome, Closed)
        # sending again on a dead connection is not an exception either
        assert isinstance(conn.request(request(Action.NONE)), Closed)
    with ScriptedBox(reset_at_once) as box:
        t = Transcript("t")
        outcome = _conn(box, t).request(request(Action.NONE))
    assert isinstance(outcome, Closed)
    assert any(e.kind in (Kind.PEER_RESET, Kind.PEER_CLOSE) for e in t.events)


def test_unreachable_is_one_clear_exception() -> None:
    import socket

    with socket.socket() as holder:  # bound, not listening: connections are refused
        holder.bind(("127.0.0.1", 0))
        t = Transcript("t")
        with pytest.raises(Unreachable, match="refused"):
            TcpConnection(t, Target("127.0.0.1", holder.getsockname()[1]), FAST).connect()
    assert t.events[-1].kind == Kind.CONNECT_FAILED


def test_pipelined_answers_come_one_by_one_and_drain_stops_on_quiet() -> None:
    with ScriptedBox(answering()) as box:
        conn = _conn(box)
        conn.send(encode(request(Action.NONE)) + encode(request(Action.CYCLE_ON)) + encode(request(Action.CYCLE_OFF)))
        got = [conn.next_outcome() for _ in range(3)]
        assert [o.frame.action for o in got if isinstance(o, Answer)] == [Action.NONE, Action.CYCLE_ON, Action.CYCLE_OFF]
        assert conn.drain(0.05) == []


def test_send_pieces_records_each_segment() -> None:
    with ScriptedBox(answering()) as box:
        t = Transcript("t")
        conn = _conn(box, t)
        wire = encode(request(Action.NONE))
        assert conn.send_pieces([wire[:3], wire[3:9], wire[9:]], note="split")
        assert isinstance(conn.next_outcome(), Answer)
    sends = [e for e in t.events if e.kind == Kind.SEND]
    assert [len(e.data) for e in sends] == [3, 6, 5] and sends[0].note == "split piece 1/3"


def test_udp_channel_decodes_datagrams_and_times_out() -> None:
    import socket
    import threading

    server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    server.bind(("127.0.0.1", 0))
    server.settimeout(2)

    def serve() -> None:
        data, addr = server.recvfrom(2048)
        server.sendto(encode(answer(Action.NONE), FAST, "udp"), addr)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    t = Transcript("t")
    ch = UdpChannel(t, Target("127.0.0.1", server.getsockname()[1]), FAST)
    outcome = ch.request(request(Action.NONE))
    assert isinstance(outcome, Answer) and outcome.frame.action == Action.NONE
    assert isinstance(ch.next_outcome(0.05), Silence)
    ch.close()
    server.close()
    assert [e.kind for e in t.events] == [Kind.SEND, Kind.RECV]


def test_bytes_sent_before_a_reset_are_recorded_before_it() -> None:
    import socket
    import struct

    def read_then_reset(conn: socket.socket) -> None:
        conn.recv(100)
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        conn.close()

    with ScriptedBox(read_then_reset) as box:
        t = Transcript("t")
        conn = _conn(box, t)
        assert conn.send(b"\x00" * 20_000_000, "a big send the box resets") is False
    kinds = [e.kind for e in t.events]
    assert Kind.SEND in kinds and kinds.index(Kind.SEND) < kinds.index(Kind.PEER_RESET)


def test_a_reset_right_after_accept_is_an_outcome_not_an_exception(monkeypatch: pytest.MonkeyPatch) -> None:
    """The box accepts and resets before we ask for the peer's address (a race seen in CI)."""
    import errno
    import socket

    import conformance.harness.client as client

    class GoneAtOnce(socket.socket):
        def getpeername(self):  # type: ignore[no-untyped-def]
            raise OSError(errno.ENOTCONN, "Transport endpoint is not connected")

    real = socket.create_connection

    def create_connection(address, timeout=None):  # type: ignore[no-untyped-def]
        return GoneAtOnce(fileno=real(address, timeout=timeout).detach())

    with ScriptedBox(silent) as box:
        monkeypatch.setattr(client.socket, "create_connection", create_connection)
        t = Transcript("t")
        conn = _conn(box, t)
        outcome = conn.request(request(Action.NONE))
    assert isinstance(outcome, Closed) and outcome.reset
    assert [e.kind for e in t.events][:2] == [Kind.CONNECT, Kind.PEER_RESET]


def test_a_reset_during_connect_is_a_closed_outcome(monkeypatch: pytest.MonkeyPatch) -> None:
    """On a loaded machine the box's reset at accept can reach create_connection itself (ECONNRESET):
    the box was reached, so that is what it did (Closed), not an unreachable target."""
    import errno
    import socket

    def reset(*args: object, **kw: object) -> socket.socket:
        raise ConnectionResetError(errno.ECONNRESET, "Connection reset by peer")

    monkeypatch.setattr(socket, "create_connection", reset)
    t = Transcript("t")
    conn = TcpConnection(t, Target("127.0.0.1", 9), FAST).connect()
    outcome = conn.request(request(Action.NONE))
    assert isinstance(outcome, Closed) and outcome.reset
    assert [e.kind for e in t.events][:2] == [Kind.CONNECT, Kind.PEER_RESET]
