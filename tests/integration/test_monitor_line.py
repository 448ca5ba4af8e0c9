"""The monitor as a line: byte-exact both ways however segmented, and an upstream that refuses,
resets or floods; UDP too. Raw asyncio peers on loopback stand in for robot and box (each test
well under a few seconds)."""

from __future__ import annotations

import asyncio
import random
import socket
from pathlib import Path

from conformance.analyze import AnalyzeConfig, analyze
from tests.monitor_util import monitored

WAIT = 10.0


async def _send_in_pieces(writer: asyncio.StreamWriter, data: bytes, rng: random.Random) -> None:
    at = 0
    while at < len(data):
        n = rng.choice((1, 2, 3, 7, 12, 39, 500, 4096, 70000))
        writer.write(data[at : at + n])
        at += n
        await writer.drain()
        if rng.random() < 0.2:
            await asyncio.sleep(0.001)


async def _read_exactly(reader: asyncio.StreamReader, n: int) -> bytes:
    return await asyncio.wait_for(reader.readexactly(n), WAIT)


def test_bytes_pass_unchanged_both_ways_however_segmented(tmp_path: Path) -> None:
    rng = random.Random(5)
    # iSight frames and garbage mixed: what a robot and a box might send, and what they must not
    frame = bytes.fromhex("fefe0001012301011900") + bytes(29)
    to_box = b"".join(rng.choice([frame, rng.randbytes(rng.randrange(1, 60)), b"\xfe", b"\xfe\xfe"])
                      for _ in range(3000))
    to_robot = rng.randbytes(300_000)
    got_by_box = bytearray()

    async def box(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        sender = asyncio.ensure_future(_send_in_pieces(writer, to_robot, random.Random(9)))
        got_by_box.extend(await _read_exactly(reader, len(to_box)))
        await sender
        writer.close()

    async def main():  # type: ignore[no-untyped-def]
        server = await asyncio.start_server(box, "127.0.0.1", 0)
        port = server.sockets[0].getsockname()[1]
        async with monitored(port, tmp_path) as m:
            reader, writer = await asyncio.open_connection(*m.target)
            sender = asyncio.ensure_future(_send_in_pieces(writer, to_box, rng))
            got = await _read_exactly(reader, len(to_robot))
            await sender
            writer.close()
        server.close()
        return m, got

    m, got = asyncio.run(main())
    assert got == to_robot
    assert bytes(got_by_box) == to_box
    assert m.monitor_json()["bytes"] == {"robot": len(to_box), "box": len(to_robot)}
    # the capture holds every byte, in order: analyze reads it whole
    pcap = sorted((tmp_path / "pcaps").glob("*.pcapng"))[0]
    analysis = analyze(pcap, AnalyzeConfig(ports=(m.settings.upstream[1],), heuristic=False))
    assert analysis.ctx.stats.gaps == 0 and analysis.ctx.stats.tcp_connections == 1


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # nothing listens there once the socket closes


def test_an_upstream_that_refuses_closes_the_robot_side_and_is_recorded(tmp_path: Path) -> None:
    async def main():  # type: ignore[no-untyped-def]
        async with monitored(_free_port(), tmp_path) as m:
            reader, writer = await asyncio.open_connection(*m.target)
            try:
                end = await asyncio.wait_for(reader.read(100), WAIT)
            except ConnectionResetError:
                end = b""
            writer.close()
        return m, end

    m, end = asyncio.run(main())
    assert end == b""
    doc = m.monitor_json()
    assert doc["upstream_failures"] == 1 and "refused" in doc["events"][0]


def test_an_upstream_that_resets_resets_the_robot_and_others_carry_on(tmp_path: Path) -> None:
    async def box(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        data = await reader.read(100)
        if data == b"reset me":
            sock = writer.get_extra_info("socket")
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
            writer.transport.abort()
            return
        writer.write(data)
        await writer.drain()
        writer.close()

    async def main():  # type: ignore[no-untyped-def]
        server = await asyncio.start_server(box, "127.0.0.1", 0)
        async with monitored(server.sockets[0].getsockname()[1], tmp_path) as m:
            r1, w1 = await asyncio.open_connection(*m.target)
            w1.write(b"reset me")
            try:
                first = await asyncio.wait_for(r1.read(100), WAIT)
            except ConnectionResetError:
                first = b""
            r2, w2 = await asyncio.open_connection(*m.target)
            w2.write(b"echo")
            second = await asyncio.wait_for(r2.read(100), WAIT)
            w1.close()
            w2.close()
        server.close()
        return m, first, second

    m, first, second = asyncio.run(main())
    assert first == b"" and second == b"echo"
    assert any("reset" in e for e in m.monitor_json()["events"])


def test_a_flooding_upstream_is_held_back_and_does_not_stall_the_others(tmp_path: Path) -> None:
    sent = [0]

    async def box(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        hello = await reader.read(100)
        if hello != b"flood":
            writer.write(hello)
            await writer.drain()
            writer.close()
            return
        block = bytes(range(256)) * 256
        try:
            while True:
                writer.write(block)
                await writer.drain()
                sent[0] += len(block)
        except (ConnectionError, OSError):
            pass

    async def main():  # type: ignore[no-untyped-def]
        server = await asyncio.start_server(box, "127.0.0.1", 0)
        async with monitored(server.sockets[0].getsockname()[1], tmp_path, pcaps=False) as m:
            r1, w1 = await asyncio.open_connection(*m.target, limit=1024)
            w1.write(b"flood")  # and never read: the monitor must stop reading the box
            await asyncio.sleep(1.0)
            r2, w2 = await asyncio.open_connection(*m.target)
            w2.write(b"still here")
            other = await asyncio.wait_for(r2.read(100), WAIT)
            flooded = sent[0]
            w1.transport.abort()
            w2.close()
        server.close()
        return other, flooded

    other, flooded = asyncio.run(main())
    assert other == b"still here"
    # the box could send only what the socket buffers hold: the monitor read no more than it could pass on
    assert 0 < flooded < 64 << 20, flooded


def test_udp_datagrams_pass_unchanged_both_ways(tmp_path: Path) -> None:
    class Echo(asyncio.DatagramProtocol):
        def connection_made(self, transport):  # type: ignore[no-untyped-def]
            self.transport = transport

        def datagram_received(self, data, addr):  # type: ignore[no-untyped-def]
            self.transport.sendto(data[::-1], addr)

    class Client(asyncio.DatagramProtocol):
        def __init__(self) -> None:
            self.got: asyncio.Queue[bytes] = asyncio.Queue()

        def datagram_received(self, data, addr):  # type: ignore[no-untyped-def]
            self.got.put_nowait(data)

    async def main():  # type: ignore[no-untyped-def]
        loop = asyncio.get_running_loop()
        box, _ = await loop.create_datagram_endpoint(Echo, local_addr=("127.0.0.1", 0))
        port = box.get_extra_info("sockname")[1]
        # the TCP side listens on the same port number: a TCP box is not needed for this test
        async with monitored(port, tmp_path, udp=True) as m:
            client, proto = await loop.create_datagram_endpoint(Client, remote_addr=m.target)
            sent = [bytes.fromhex("fefe000101000000000000000000"), b"\x00" * 3, bytes(range(200))]
            got = []
            for data in sent:
                client.sendto(data)
                got.append(await asyncio.wait_for(proto.got.get(), WAIT))
            client.close()
        box.close()
        return m, sent, got

    m, sent, got = asyncio.run(main())
    assert got == [d[::-1] for d in sent]
    assert m.monitor_json()["bytes"] == {"robot": sum(map(len, sent)), "box": sum(map(len, sent))}
