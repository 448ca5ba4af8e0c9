"""The certify-robot listener: answers as the reference box, records every connection,
tells sessions apart, bounds every wait, injects, and never lets an exception escape."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable

import pytest

from conformance.certify.listener import CertifyListener
from conformance.certify.records import CertifyConfig, RunRecord
from conformance.harness.transcript import Kind
from conformance.observed.connections import BY_BOX, BY_ROBOT, BY_SUITE
from conformance.protocol import Action, Profile, encode, encode_udp, request
from tests.unit.test_observed_session import POSE, frame

pytestmark = pytest.mark.timeout(30)

ANSWER_LEN = 14

Client = Callable[[CertifyListener], Awaitable[None]]


def listen(client: Client, **config) -> RunRecord:
    config.setdefault("wait_s", 5.0)
    cfg = CertifyConfig(host="127.0.0.1", port=0, **config)

    async def main() -> RunRecord:
        listener = CertifyListener(cfg)
        await listener.start()
        task = asyncio.create_task(listener.run())
        await client(listener)
        return await task

    return asyncio.run(main())


async def connect(listener: CertifyListener) -> tuple[asyncio.StreamReader, asyncio.StreamWriter]:
    return await asyncio.open_connection("127.0.0.1", listener.tcp_port)


async def nothing(listener: CertifyListener) -> None:
    pass


def test_describe_and_one_port_for_tcp_and_udp():
    seen = []

    async def client(listener):
        seen.append(listener.describe())
        assert listener.udp_port == listener.tcp_port

    run = listen(client, wait_s=0.1)
    assert seen[0] == f"listening tcp 127.0.0.1:{run.tcp_port} udp 127.0.0.1:{run.tcp_port}"
    assert run.end_reason == "wait" and run.sessions == []
    assert run.end_note == "no robot connected within --wait 0.1 s"


def test_a_session_is_recorded_and_ends_when_both_connections_close(tmp_path):
    async def client(listener):
        r1, w1 = await connect(listener)
        r2, w2 = await connect(listener)
        w2.write(POSE + POSE)
        assert len(await r2.readexactly(2 * ANSWER_LEN)) == 28
        w1.write(frame(Action.CYCLE_ON))
        await r1.readexactly(ANSWER_LEN)
        w2.close()
        assert await r2.read() == b""  # the box closes its side after our FIN (S5)
        w1.close()
        assert await r1.read() == b""

    run = listen(client, pcap_dir=tmp_path)
    assert run.end_reason == "complete" and len(run.sessions) == 1
    session = run.sessions[0]
    assert session.end_reason == "all connections closed"
    cmd, stream = session.conns
    assert (cmd.role, stream.role) == ("command", "stream")
    assert cmd.closed_by == stream.closed_by == BY_ROBOT
    kinds = [e.kind for e in stream.transcript.events]
    assert kinds[0] == Kind.CONNECT and stream.transcript.events[0].note.startswith("accepted from robot")
    assert kinds[-2:] == [Kind.PEER_CLOSE, Kind.CLOSE]
    assert stream.transcript.connections[1].local.port == run.tcp_port  # local is the box
    assert [e.offset for e in stream.exchanges] == [0, 39]
    assert all(e.t_answer is not None and e.t_answer >= e.t_request for e in stream.exchanges)
    assert cmd.exchanges[0].action == Action.CYCLE_ON and cmd.exchanges[0].error_code == 0
    assert cmd.pcap is not None and cmd.pcap.exists() and cmd.pcap.stat().st_size > 0


def test_a_stream_only_session_waits_for_the_grace_period():
    async def client(listener):
        _r, w = await connect(listener)
        w.write(POSE)
        await asyncio.sleep(0.05)
        w.close()

    run = listen(client, grace_s=0.2)
    assert len(run.sessions) == 1 and run.sessions[0].conns[0].role == "stream"
    assert run.sessions[0].t_end is not None


def test_connections_left_open_after_the_command_connection_are_closed_by_the_suite():
    async def client(listener):
        r1, w1 = await connect(listener)
        r2, w2 = await connect(listener)
        w2.write(POSE)
        await r2.readexactly(ANSWER_LEN)
        w1.write(frame(Action.CYCLE_ON))
        await r1.readexactly(ANSWER_LEN)
        w1.close()
        assert await asyncio.wait_for(r2.read(), 5) == b""  # closed by the suite after --linger
        w2.close()

    run = listen(client, linger_s=0.2)
    cmd, stream = run.sessions[0].conns
    assert cmd.closed_by == BY_ROBOT and stream.closed_by == BY_SUITE
    assert "--linger" in stream.close_note and "--linger" in run.sessions[0].end_reason


def test_a_silent_session_is_cut_off_after_wait():
    async def client(listener):
        _r, w = await connect(listener)
        await asyncio.sleep(0.6)
        w.close()

    run = listen(client, wait_s=0.3)
    conn = run.sessions[0].conns[0]
    assert conn.closed_by == BY_SUITE and "nothing happened for --wait 0.3 s" in conn.close_note


def test_refused_after_the_sessions_are_done():
    async def client(listener):
        _r, w = await connect(listener)
        w.write(frame(Action.NONE))
        w.close()

    run = listen(client, sessions=1)
    assert run.end_reason == "complete"

    async def late():
        with pytest.raises(OSError):
            await asyncio.open_connection("127.0.0.1", run.tcp_port)

    asyncio.run(late())


def test_slow_holds_every_answer_back():
    profile = Profile(time_out_ms=250)

    async def client(listener):
        r, w = await connect(listener)
        w.write(frame(Action.CYCLE_ON))
        await r.readexactly(ANSWER_LEN)
        w.close()

    run = listen(client, inject=("slow",), profile=profile)
    (exchange,) = run.sessions[0].conns[0].exchanges
    assert exchange.t_answer is not None and exchange.t_answer - exchange.t_request >= 0.2


def test_close_mid_cycle_closes_the_command_connection_after_the_answer():
    async def client(listener):
        r1, w1 = await connect(listener)
        r2, w2 = await connect(listener)
        w2.write(POSE)
        await r2.readexactly(ANSWER_LEN)
        w1.write(frame(Action.CYCLE_ON))
        assert len(await r1.readexactly(ANSWER_LEN)) == ANSWER_LEN
        assert await r1.read() == b""
        w2.close()
        w1.close()

    run = listen(client, inject=("close-mid-cycle",))
    session = run.sessions[0]
    cmd = session.conns[0]
    assert cmd.closed_by == BY_BOX and "close-mid-cycle" in cmd.close_note
    assert [e.name for e in session.injected] == ["close-mid-cycle"]


def test_not_ready_and_busy_answers():
    async def client(listener):
        r, w = await connect(listener)
        w.write(frame(Action.CYCLE_ON))
        await r.readexactly(ANSWER_LEN)
        w.write(frame(Action.VISION_RESULT))
        await r.readexactly(ANSWER_LEN + 5)
        w.close()

    run = listen(client, inject=("not-ready", "busy"))
    on, result = run.sessions[0].conns[0].exchanges
    assert on.error_code == 1 and result.value == 202


def test_udp_datagrams_are_recorded_and_answered():
    async def client(listener):
        loop = asyncio.get_running_loop()
        got: asyncio.Future = loop.create_future()

        class Proto(asyncio.DatagramProtocol):
            def datagram_received(self, data, addr):
                if not got.done():
                    got.set_result(data)

        transport, _ = await loop.create_datagram_endpoint(Proto, remote_addr=("127.0.0.1", listener.udp_port))
        transport.sendto(encode_udp(request(Action.NONE)))
        assert len(await asyncio.wait_for(got, 5)) == ANSWER_LEN
        transport.close()
        _r, w = await connect(listener)
        w.close()

    run = listen(client)
    udp = [c for c in run.sessions[0].conns if c.transport == "udp"]
    assert len(udp) == 1 and udp[0].exchanges[0].t_answer is not None
    assert [e.kind for e in udp[0].transcript.events] == [Kind.CONNECT, Kind.RECV, Kind.SEND]


def test_the_suites_own_failure_is_recorded_not_raised():
    async def client(listener):
        def broken(event, transport=None):
            raise RuntimeError("box logic exploded")

        listener.behaviour.decide = broken  # type: ignore[method-assign]
        listener.behaviour.fast_path = False  # every frame through the patched decide()
        r, w = await connect(listener)
        w.write(frame(Action.CYCLE_ON))
        await asyncio.sleep(0.1)
        w.close()
        await r.read()

    run = listen(client)
    assert run.errors and "box logic exploded" in run.errors[0]
    assert run.sessions[0].conns[0].t_close is not None


def test_stop_ends_the_run_and_closes_what_is_open():
    async def client(listener):
        r, w = await connect(listener)
        w.write(encode(request(Action.NONE)))
        await r.readexactly(ANSWER_LEN)
        listener.stop("stopped by signal SIGINT")
        assert await asyncio.wait_for(r.read(), 5) == b""
        w.close()

    run = listen(client)
    assert run.end_reason == "interrupted" and run.end_note == "stopped by signal SIGINT"
    assert run.sessions[0].conns[0].closed_by == BY_SUITE


def test_events_are_reported():
    lines: list[str] = []
    cfg = CertifyConfig(host="127.0.0.1", port=0, wait_s=5)

    async def main():
        listener = CertifyListener(cfg, on_event=lines.append)
        await listener.start()
        task = asyncio.create_task(listener.run())
        _r, w = await asyncio.open_connection("127.0.0.1", listener.tcp_port)
        w.write(frame(Action.NONE))
        w.close()
        await task

    asyncio.run(main())
    assert lines[0] == "session 1: started"
    assert lines[1].startswith("session 1: connection 1 accepted from 127.0.0.1:")
    assert "session 1: connection 1 (command) closed by robot" in lines
    assert lines[-1] == "session 1: ended (all connections closed)"
