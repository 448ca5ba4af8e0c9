"""Live alarms (issue 26): a box silent past time_out, a stream below its rate, a connection the box
refuses are findings the moment they happen, while the connection stays open; a late answer is
recorded on its alarm. Raw asyncio peers on loopback stand in for robot and box; waits are bounded."""

from __future__ import annotations

import asyncio
import dataclasses
import socket
import time
from pathlib import Path

from conformance.protocol import DEFAULT_PROFILE, Action, answer, encode, pose_blocks, request
from tests.monitor_util import monitored

FAST = dataclasses.replace(DEFAULT_PROFILE, time_out_ms=400)
CYCLE_ON = encode(request(Action.CYCLE_ON))
POSE = encode(request(Action.POSE, pose_blocks([(800.0, 0.0, 500.0, 180.0, 0.0, 0.0)])))


async def _until(predicate, bound: float = 10.0) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        if predicate():
            return True
        await asyncio.sleep(0.02)
    return False


async def _late_box(delay: float, answered: asyncio.Event) -> tuple[asyncio.Server, int]:
    """A box that answers each 14-byte request ``delay`` seconds late."""
    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while True:
                data = await reader.readexactly(14)
                await asyncio.sleep(delay)
                writer.write(encode(answer(Action(data[5]))))
                await writer.drain()
                answered.set()
        except (asyncio.IncompleteReadError, ConnectionError):
            writer.close()

    server = await asyncio.start_server(serve, "127.0.0.1", 0)
    return server, server.sockets[0].getsockname()[1]


def test_a_box_silent_past_time_out_alarms_while_the_connection_is_open_and_the_late_answer_is_recorded(
        tmp_path: Path) -> None:
    async def main():  # type: ignore[no-untyped-def]
        answered = asyncio.Event()
        server, port = await _late_box(2.0, answered)
        async with monitored(port, tmp_path, profile=FAST) as m:
            reader, writer = await asyncio.open_connection(*m.target)
            writer.write(CYCLE_ON)
            sent = time.monotonic()
            hub = m.view.hub  # type: ignore[union-attr]
            raised = await _until(lambda: bool(hub.alarms.active), 5.0)
            raised_after = time.monotonic() - sent
            active = [a.to_dict() for a in hub.alarms.active.values()]
            got = await asyncio.wait_for(reader.readexactly(14), 10)  # the late answer reaches the robot
            cleared = await _until(lambda: not hub.alarms.active, 5.0)
            writer.close()
            await m.settled()
        server.close()
        return m, raised, raised_after, active, got, cleared

    m, raised, raised_after, active, got, cleared = asyncio.run(main())
    assert raised and raised_after < 1.9, raised_after  # before the answer came (2 s), not at the close
    assert active[0]["kind"] == "box-silent" and active[0]["clause"] == "T1" and active[0]["side"] == "box"
    assert "CYCLE_ON" in active[0]["what"] and "still open" in active[0]["what"]
    assert got[5] == Action.CYCLE_ON and cleared
    doc = m.monitor_json()
    alarm = doc["alarms"][0]
    assert not alarm["active"] and alarm["outcome"].startswith("answered late") and "CYCLE_ON" in alarm["outcome"]
    assert doc["alarms_raised"]["box-silent"] == 1 and doc["alarms_active"] == 0
    assert "ALARM BOX T1 [box-silent]" in m.view_out.getvalue()


def test_an_answer_within_time_out_raises_no_alarm(tmp_path: Path) -> None:
    async def main():  # type: ignore[no-untyped-def]
        answered = asyncio.Event()
        server, port = await _late_box(0.1, answered)
        async with monitored(port, tmp_path, profile=FAST) as m:
            reader, writer = await asyncio.open_connection(*m.target)
            for _ in range(3):
                writer.write(CYCLE_ON)
                await asyncio.wait_for(reader.readexactly(14), 10)
            await asyncio.sleep(0.8)  # past time_out after the last answer: nothing waits
            writer.close()
            await m.settled()
        server.close()
        return m

    m = asyncio.run(main())
    assert m.monitor_json()["alarms"] == []


def test_a_stream_below_its_rate_alarms_and_clears_when_it_recovers(tmp_path: Path) -> None:
    async def main():  # type: ignore[no-untyped-def]
        server, port = await _pose_box()
        async with monitored(port, tmp_path) as m:  # 50 Hz declared
            hub = m.view.hub  # type: ignore[union-attr]
            reader, writer = await asyncio.open_connection(*m.target)
            drain = asyncio.ensure_future(_drain(reader))
            slow = await _stream(writer, 10.0, 6.0, lambda: bool(hub.alarms.active))
            what = [a.to_dict() for a in hub.alarms.active.values()]
            recovered = await _stream(writer, 50.0, 8.0, lambda: not hub.alarms.active)
            writer.close()
            drain.cancel()
            await m.settled()
        server.close()
        return m, slow, what, recovered

    m, slow, what, recovered = asyncio.run(main())
    assert slow, "no alarm for a 10 Hz stream declared at 50 Hz"
    assert what[0]["kind"] == "stream-slow" and what[0]["side"] == "robot" and what[0]["clause"] == "T2"
    assert recovered
    assert "the stream is back" in m.monitor_json()["alarms"][0]["outcome"]


async def _pose_box() -> tuple[asyncio.Server, int]:
    async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while True:
                data = await reader.readexactly(len(POSE))
                writer.write(encode(answer(Action(data[5]))))
        except (asyncio.IncompleteReadError, ConnectionError):
            writer.close()

    server = await asyncio.start_server(serve, "127.0.0.1", 0)
    return server, server.sockets[0].getsockname()[1]


async def _drain(reader: asyncio.StreamReader) -> None:
    while await reader.read(65536):
        pass


async def _stream(writer: asyncio.StreamWriter, hz: float, bound: float, until) -> bool:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + bound
    while time.monotonic() < deadline:
        writer.write(POSE)
        await writer.drain()
        await asyncio.sleep(1.0 / hz)
        if until():
            return True
    return False


def test_a_connection_the_box_refuses_alarms_until_it_accepts_one(tmp_path: Path) -> None:
    with socket.socket() as s:  # a port nobody listens on (bound, not listening: refused)
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]

        async def main():  # type: ignore[no-untyped-def]
            async with monitored(port, tmp_path) as m:
                hub = m.view.hub  # type: ignore[union-attr]
                _reader, writer = await asyncio.open_connection(*m.target)
                raised = await _until(lambda: bool(hub.alarms.active), 5.0)
                active = [a.to_dict() for a in hub.alarms.active.values()]
                writer.close()
                await m.settled()
            return m, raised, active

        m, raised, active = asyncio.run(main())
    assert raised and active[0]["kind"] == "box-refused" and active[0]["side"] == "box"
    assert "refused" in active[0]["what"]
    assert m.monitor_json()["alarms_active"] == 1  # nothing the box accepted cleared it
