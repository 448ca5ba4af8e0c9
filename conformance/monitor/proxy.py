"""The TCP side of the monitor: robot ↔ monitor ↔ box, byte for byte (asyncio).

Every robot connection gets its own connection to the box. Two pumps copy bytes, one
each way; each reads at most :data:`CHUNK` bytes, writes them on, tells the
:class:`~.hub.Hub` (which records and judges them), and waits until the other socket's
send buffer drains below asyncio's high-water mark before it reads again: a side that
does not read stops the other side's reads (backpressure), so a connection holds at
most a chunk plus one send buffer, and a flood from either side never fills memory.

Closes travel as they came: a FIN becomes a FIN (half-close) on the other socket, a
reset becomes an abort. A box that cannot be reached (refused, or no answer within
``connect_timeout_s``) or that resets gets the robot's connection reset, and the hub
records it. Nothing a peer does raises out of a pump.

With ``--fault`` specs the box → robot pump cuts the box's bytes into frames
(:class:`~.split.Splitter`) and applies the first spec that matches each answer
(:mod:`.faults`); bytes no spec touches pass unchanged.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
from typing import Any

from ..protocol import DEFAULT_PROFILE, Header, TransferType, codec_for, peek_header, peek_transfer_type
from .faults import Fault, corrupt
from .hub import Conn, Hub
from .split import Splitter

__all__ = ["CHUNK", "TcpProxy"]

CHUNK = 65000  # one synthesised segment at most (evidence.packet_builder.MAX_SEGMENT)
_ANSWER = int(TransferType.BOX_TO_ROBOT)


def _nodelay(writer: asyncio.StreamWriter) -> None:
    sock = writer.get_extra_info("socket")
    if sock is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


def _abort(writer: asyncio.StreamWriter) -> None:
    with contextlib.suppress(Exception):
        writer.transport.abort()


def _eof(writer: asyncio.StreamWriter) -> None:
    with contextlib.suppress(Exception):
        if writer.can_write_eof():
            writer.write_eof()
        else:
            writer.close()


class TcpProxy:
    def __init__(self, hub: Hub) -> None:
        self.hub = hub
        self.settings = hub.settings
        self.server: asyncio.AbstractServer | None = None
        self.tasks: set[asyncio.Task[Any]] = set()
        self.stall_until = 0.0  # loop time until which every answer is held (stall fault)
        self.address: tuple[str, int] | None = None

    async def start(self) -> tuple[str, int]:
        host, port = self.settings.listen
        self.server = await asyncio.start_server(self._accept, host, port, limit=CHUNK)
        self.address = self.server.sockets[0].getsockname()[:2]
        return self.address

    async def stop(self) -> None:
        if self.server is not None:
            self.server.close()
        for task in list(self.tasks):
            task.cancel()
        if self.tasks:
            await asyncio.gather(*self.tasks, return_exceptions=True)

    # -- one robot connection ----------------------------------------------------------------------
    async def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is not None:
            self.tasks.add(task)
        try:
            await self._serve(reader, writer)
        except asyncio.CancelledError:
            _abort(writer)
        finally:
            if task is not None:
                self.tasks.discard(task)

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer = writer.get_extra_info("peername") or ("?", 0)
        hub = self.hub
        conn = hub.opened((peer[0], peer[1]), self.settings.upstream)
        _nodelay(writer)
        timeout = self.settings.connect_timeout_s
        try:
            up_r, up_w = await asyncio.wait_for(asyncio.open_connection(*self.settings.upstream, limit=CHUNK), timeout)
        except (asyncio.TimeoutError, TimeoutError):
            hub.upstream_failed(conn, f"did not accept a connection within {timeout:g} s")
            _abort(writer)
            hub.gone(conn)
            return
        except OSError as exc:
            hub.upstream_failed(conn, f"refused the connection ({exc.strerror or exc})")
            _abort(writer)
            hub.gone(conn)
            return
        _nodelay(up_w)
        hub.upstream_ok(conn)
        pumps = [asyncio.ensure_future(self._robot_to_box(conn, reader, up_w, writer)),
                 asyncio.ensure_future(self._box_to_robot(conn, up_r, writer, up_w))]
        try:
            await asyncio.gather(*pumps)
        finally:
            for p in pumps:
                p.cancel()
            for w in (writer, up_w):
                with contextlib.suppress(Exception):
                    w.close()
            hub.gone(conn)

    async def _robot_to_box(self, conn: Conn, reader: asyncio.StreamReader, up_w: asyncio.StreamWriter,
                            writer: asyncio.StreamWriter) -> None:
        hub = self.hub
        while True:
            try:
                data = await reader.read(CHUNK)
            except OSError:  # the robot reset its connection
                hub.closed(conn, from_robot=True, reset=True)
                _abort(up_w)
                return
            if not data:
                hub.closed(conn, from_robot=True)
                _eof(up_w)
                return
            up_w.write(data)
            hub.data(conn, True, data)
            try:
                await up_w.drain()
            except OSError:  # the box's socket failed: its pump tells how
                return

    async def _box_to_robot(self, conn: Conn, up_r: asyncio.StreamReader, writer: asyncio.StreamWriter,
                            up_w: asyncio.StreamWriter) -> None:
        hub = self.hub
        split = Splitter(hub.big_endian) if hub.faults else None
        while True:
            try:
                data = await up_r.read(CHUNK)
            except OSError as exc:  # the box reset the connection: so does the robot's
                hub.note(f"connection {conn.line.number}: the box reset it ({exc.strerror or exc})")
                hub.closed(conn, from_robot=False, reset=True)
                _abort(writer)
                _abort(up_w)
                return
            if not data:
                if split is not None and split.pending:
                    await self._send(conn, writer, split.flush())
                hub.closed(conn, from_robot=False)
                _eof(writer)
                return
            if split is None:
                writer.write(data)
                hub.data(conn, False, data)
                ok = await self._drain(writer)
            else:
                ok = await self._shaped(conn, split.feed(data), writer, up_w)
            if not ok:
                return

    async def _drain(self, writer: asyncio.StreamWriter) -> bool:
        try:
            await writer.drain()
        except OSError:  # the robot's socket failed: its pump tells how
            return False
        return True

    async def _send(self, conn: Conn, writer: asyncio.StreamWriter, data: bytes,
                    comments: list[str] | None = None) -> int:
        if writer.is_closing():
            return 0
        writer.write(data)
        frame = self.hub.data(conn, False, data, comments)
        await self._drain(writer)
        return frame

    # -- faults ---------------------------------------------------------------------------------------
    async def _shaped(self, conn: Conn, pieces: list[tuple[bytes, int | None]], writer: asyncio.StreamWriter,
                      up_w: asyncio.StreamWriter) -> bool:
        """The box's pieces with the faults applied; False when the robot's connection was closed."""
        hub, loop = self.hub, asyncio.get_running_loop()
        pending = bytearray()
        for piece, action in pieces:
            answer = action is not None and peek_transfer_type(piece) == _ANSWER
            request = hub.answered(conn, action) if answer and action is not None else None
            fault = hub.pick(action) if answer and action is not None else None
            held = self.stall_until - loop.time() if answer else 0.0
            if fault is None and held <= 0:
                pending += piece
                continue
            if pending:
                await self._send(conn, writer, bytes(pending))
                pending.clear()
            if fault is not None and action is not None:
                if not await self._inject(conn, fault, action, piece, request, writer, up_w):
                    return False
                continue
            note = f"answer held {held * 1000:.0f} ms by an injected stall"
            hub.findings.fault_on(conn.line.number, min(hub.wire.frames + 1, request or hub.wire.frames + 1), 0)
            await asyncio.sleep(held)
            await self._send(conn, writer, piece, [f"isight-conformance monitor: INJECTED FAULT: {note}"])
        if pending:
            await self._send(conn, writer, bytes(pending))
        return not writer.is_closing()

    async def _inject(self, conn: Conn, fault: Fault, action: int, piece: bytes, request: int | None,
                      writer: asyncio.StreamWriter, up_w: asyncio.StreamWriter) -> bool:
        from ..protocol import action_name

        hub, kind, name = self.hub, fault.kind, action_name(action)
        if kind == "stall":
            self.stall_until = asyncio.get_running_loop().time() + fault.ms / 1000.0
            kind, what = "delay", f"every answer held {fault.ms:.0f} ms from this {name} answer on (stall)"
        else:
            what = {"delay": f"{name} answer delayed {fault.ms:.0f} ms", "drop": f"{name} answer dropped",
                    "error": f"{name} answered with error code {fault.code} instead",
                    "corrupt": f"{name} answer's {fault.field_name} field inverted",
                    "close": f"the robot's connection closed instead of the {name} answer"}[kind]
        inj = hub.injected(conn, fault, action, what, request)
        comment = [hub.comment(fault, what)]
        if kind == "delay":
            try:
                await asyncio.sleep(fault.ms / 1000.0)
            except asyncio.CancelledError:
                inj.frame = hub.wire.marker(conn.line, False, comment[0] + "; the monitor stopped before it was due")
                raise
            inj.frame = await self._send(conn, writer, piece, comment)
            if not inj.frame:  # the robot's connection is gone: the late answer had nowhere to go
                inj.frame = hub.wire.marker(conn.line, False, comment[0] + "; the robot's connection was closed "
                                            "before it was due, so it was not sent")
        elif kind == "drop":
            hub.wire.marker(conn.line, False, comment[0] + f" (the box's bytes: {piece[:64].hex(' ')})")
        elif kind == "error":
            await self._send(conn, writer, self._error_answer(piece, fault.code), comment)
        elif kind == "corrupt":
            await self._send(conn, writer, corrupt(piece, fault.field_name), comment)
        else:  # close
            hub.closed(conn, from_robot=False, comment=comment[0])
            _eof(writer)
            writer.close()
            _eof(up_w)
            return False
        return True

    def _error_answer(self, piece: bytes, code: int) -> bytes:
        """The answer's header with no blocks and ``code`` (in the profile's byte order), check 00 00."""
        order = "big" if self.hub.big_endian else "little"
        head = peek_header(piece, 0, order)  # a whole frame's: the splitter cut it
        assert head is not None
        return codec_for(DEFAULT_PROFILE.replace(byte_order=order)).encode_raw(
            Header(transfer_type=head.transfer_type, action=head.action, error_code=code))
