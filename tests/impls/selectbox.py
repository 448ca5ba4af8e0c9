"""selectbox: a conforming AI Box written from docs/PROTOCOL.md alone, on one thread.

It shares nothing with the project (no import from ``conformance`` or the other boxes of
``tests/impls``): its own codec with ``struct``, its own framer, and a single-threaded
``selectors`` event loop over non-blocking sockets. It makes legal choices that the other
boxes do not, each named by the clause that allows it:

- every answer is delayed by a random latency (per request, below ``time_out / 2``, T1) and
  written in two or three pieces with short pauses between them (a receiver reassembles, R3);
- answers on one connection keep request order (A1) whatever their latencies;
- the cycle state is kept per connection, CycleOn twice answered 0000 both times, CycleOff
  without CycleOn 0002; or (``box-cycle``) box-wide, owned by the connection that opened it,
  CycleOn while on answered 0001, CycleOff without CycleOn 0000 (S3: all legal);
- (``warm-up``) the first CycleOn on each connection is answered 0001, not ready (S2);
- the TCP check field: 00 00 or a correct CRC-16/MODBUS accepted, or (``box-cycle``) ignored (F6);
- a frame that is not a request (A5) is answered with a non-zero error under action ``00`` in
  the ``a5err`` configurations, or makes the box close the connection in the ``close`` ones;
- a request that breaks B3-B5 is answered with its action's error (A3), 0001 for 00/01/02;
- bytes that are not a frame: either the box resynchronises (R6 (a) for a header with a good
  start word and version, whose announced length it skips without buffering it; (b) for
  anything else) or it closes the connection (R6 (c));
- extension E present (26/27 answered, E2/E3) or absent (26/27 are unknown actions, A5);
- first block index 0 or 1 (B3 [decision]); NaN/infinity rejected (B4 SHOULD) or accepted.

Run: ``python -m tests.impls.selectbox --port 0 [--config NAME]``; the first line on stdout
is ``listening tcp 127.0.0.1:PORT``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import random
import selectors
import socket
import struct
import sys
import time

HEADER = struct.Struct(">HHBBBBHH")  # start, version, transfer, action, type, count, length, error
START, VERSION, TO_BOX, TO_ROBOT = 0xFEFE, 0x0001, 0x01, 0x10
POSE, TOL, INT = struct.Struct(">B6f"), struct.Struct(">Bf"), struct.Struct(">Bi")
# action -> (block type, block length, error code for a malformed request)
ACTIONS = {0x00: (0, 0, 0x0001), 0x01: (0, 0, 0x0001), 0x02: (0, 0, 0x0001),
           0x23: (1, 25, 0x1001), 0x24: (1, 25, 0x1001), 0x25: (2, 5, 0x1002)}
EXTENSION = {0x26: (3, 5, 0x0001), 0x27: (0, 0, 0x0001)}
MAX_BUFFER = 1 << 16  # never buffer more than this per connection (R5)


@dataclasses.dataclass(frozen=True)
class Config:
    first_index: int = 0
    extension: bool = False
    on_garbage: str = "resync"  # "resync" (R6 a/b) or "close" (R6 c)
    on_non_request: str = "a5err"  # "a5err": error under action 00; "close"; "silent"
    finite_only: bool = True  # B4 SHOULD: NaN/infinity is a parse error
    max_latency_ms: float = 200.0
    check: str = "zero-or-crc"  # TCP check field accepted: "zero-or-crc" (CRC-16/MODBUS) or "any" (ignored, F6)
    cycle_scope: str = "conn"  # the cycle state belongs to each connection or to the box (S3)
    second_cycle_on: int = 0x0000  # the answer to CycleOn while a cycle is on (S3: 0000 or an error)
    off_without_on: int = 0x0002  # the answer to CycleOff with no cycle on (S3: 0000 or an error)
    warm_up: bool = False  # the first CycleOn of each connection is answered 0001, not ready (S2)


CONFIGS = {
    "a5err": Config(),
    "ext1-close": Config(first_index=1, extension=True, on_garbage="close", on_non_request="close",
                         finite_only=False),
    "ext0-silent": Config(extension=True, on_non_request="silent", max_latency_ms=600.0),
    "slow": Config(max_latency_ms=2400.0),
    "warm-up": Config(warm_up=True, on_non_request="silent", max_latency_ms=50.0),
    "box-cycle": Config(cycle_scope="box", second_cycle_on=0x0001, off_without_on=0x0000, check="any"),
}


def crc16_modbus(data: bytes) -> int:
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def answer(action: int, error: int = 0, int_block: tuple[int, int] | None = None) -> bytes:
    if int_block is None:
        return HEADER.pack(START, VERSION, TO_ROBOT, action, 0, 0, 0, error) + b"\x00\x00"
    return HEADER.pack(START, VERSION, TO_ROBOT, action, 3, 1, 5, error) + INT.pack(*int_block) + b"\x00\x00"


class Conn:
    """One connection: its receive buffer, its framing state, its cycle and its answer queue."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.buf = bytearray()
        self.skip = 0  # bytes of a trusted bad frame still to discard (R6 a)
        self.cycle_on = False
        self.warmed = False  # a CycleOn was refused on this connection (warm-up)
        self.pieces: list[tuple[float, bytes]] = []  # (due, bytes), in order
        self.last_due = 0.0
        self.closing = False


class Box:
    def __init__(self, cfg: Config, rng: random.Random) -> None:
        self.cfg, self.rng = cfg, rng
        self.sel = selectors.DefaultSelector()
        self.conns: dict[int, Conn] = {}
        self.cycle_owner: Conn | None = None  # the connection whose CycleOn is in force (box-wide scope)

    # ---- answers -------------------------------------------------------------------------
    def send_later(self, conn: Conn, data: bytes) -> None:
        now = time.monotonic()
        due = max(conn.last_due, now + self.rng.uniform(0, self.cfg.max_latency_ms) / 1000)
        cuts = sorted(self.rng.sample(range(1, len(data)), self.rng.choice((1, 2))))
        for a, b in zip([0, *cuts], [*cuts, len(data)]):
            conn.pieces.append((due, data[a:b]))
            due += self.rng.uniform(0.001, 0.008)
        conn.last_due = due

    # ---- frames --------------------------------------------------------------------------
    def blocks_ok(self, kind: int, count: int, length: int, body: bytes) -> bool:
        for i in range(count):
            block = body[i * length:(i + 1) * length]
            if block[0] != (self.cfg.first_index + i) & 0xFF:
                return False
            values = POSE.unpack(block)[1:] if kind == 1 else TOL.unpack(block)[1:] if kind == 2 else ()
            if self.cfg.finite_only and not all(math.isfinite(v) for v in values):
                return False
        return True

    def handle(self, conn: Conn, frame: bytes) -> None:
        _, _, transfer, action, kind, count, length, _ = HEADER.unpack_from(frame)
        check = struct.unpack_from(">H", frame, len(frame) - 2)[0]
        known = ACTIONS | (EXTENSION if self.cfg.extension else {})
        if transfer != TO_BOX or action not in known:
            return self.non_request(conn)
        want_kind, want_len, err = known[action]
        body = frame[12:-2]
        crc_fine = self.cfg.check == "any" or check in (0, crc16_modbus(frame[:-2]))
        if want_kind == 0:
            shape_ok = kind == 0 and count == 0 and length == 0
        else:
            shape_ok = kind == want_kind and length == want_len and count >= 1
            if action == 0x26:
                shape_ok = shape_ok and count == 1
        if not (crc_fine and shape_ok and self.blocks_ok(kind, count, length, body)):
            return self.send_later(conn, answer(action, err))
        self.send_later(conn, self.reply(conn, action, body))

    def reply(self, conn: Conn, action: int, body: bytes) -> bytes:
        if action in (0x01, 0x02):
            return answer(action, self.cycle(conn, action == 0x01))
        elif action == 0x26:
            return answer(action, 0, (self.cfg.first_index, INT.unpack(body)[1]))
        elif action == 0x27:
            return answer(action, 0, (self.cfg.first_index, 1))
        return answer(action)

    def cycle(self, conn: Conn, on: bool) -> int:
        """CycleOn / CycleOff: the error code. A box-wide cycle belongs to the connection that opened it
        and ends when that connection closes."""
        owner = self.cycle_owner if self.cfg.cycle_scope == "box" else (conn if conn.cycle_on else None)
        if on:
            if self.cfg.warm_up and not conn.warmed:
                conn.warmed = True
                return 0x0001
            if owner is not None:
                return self.cfg.second_cycle_on
            conn.cycle_on, self.cycle_owner = True, conn
            return 0
        if owner is None:
            return self.cfg.off_without_on
        owner.cycle_on, self.cycle_owner = False, None
        return 0

    def non_request(self, conn: Conn) -> None:
        if self.cfg.on_non_request == "close":
            conn.closing = True
        elif self.cfg.on_non_request == "a5err":
            self.send_later(conn, answer(0x00, 0x0001))

    def frame_out(self, conn: Conn) -> None:
        """Cut every complete frame from the buffer; resynchronise or close on garbage."""
        buf = conn.buf
        while not conn.closing:
            if conn.skip:
                drop = min(conn.skip, len(buf))
                del buf[:drop]
                conn.skip -= drop
                if conn.skip:
                    return
            if len(buf) < 4:
                if buf and buf[0] != 0xFE or len(buf) >= 2 and buf[1] != 0xFE:
                    self.garbage(conn, buf)
                    continue
                return
            if buf[:4] != b"\xfe\xfe\x00\x01":
                self.garbage(conn, buf)
                continue
            if len(buf) < 12:
                return
            total = 14 + buf[7] * struct.unpack_from(">H", buf, 8)[0]
            if total > MAX_BUFFER:  # trust the header (R6 a): skip it without buffering it
                conn.skip = total
                if self.cfg.on_garbage != "close":
                    self.non_request_len(conn, bytes(buf[:12]))
                else:
                    conn.closing = True
                continue
            if len(buf) < total:
                return
            frame = bytes(buf[:total])
            del buf[:total]
            self.handle(conn, frame)

    def non_request_len(self, conn: Conn, header: bytes) -> None:
        action = header[5]
        known = ACTIONS | (EXTENSION if self.cfg.extension else {})
        if header[4] == TO_BOX and action in known:
            self.send_later(conn, answer(action, known[action][2]))  # too long to be well-formed
        else:
            self.non_request(conn)

    def garbage(self, conn: Conn, buf: bytearray) -> None:
        if self.cfg.on_garbage == "close":
            conn.closing = True
            return
        nxt = buf.find(b"\xfe\xfe", 1)  # R6 (b): resume at the next FE FE after the first byte
        if nxt < 0:
            keep = 1 if buf[-1:] == b"\xfe" else 0
            del buf[:len(buf) - keep]
        else:
            del buf[:nxt]

    # ---- the loop ------------------------------------------------------------------------
    def accept(self, lsock: socket.socket) -> None:
        try:
            sock, _ = lsock.accept()
        except (BlockingIOError, InterruptedError, ConnectionAbortedError):
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn = Conn(sock)
        self.conns[sock.fileno()] = conn
        self.sel.register(sock, selectors.EVENT_READ, conn)

    def read(self, conn: Conn) -> None:
        try:
            data = conn.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            return self.drop(conn)
        conn.buf += data
        self.frame_out(conn)
        if len(conn.buf) > MAX_BUFFER:
            self.drop(conn)

    def drop(self, conn: Conn) -> None:
        fd = conn.sock.fileno()
        if fd in self.conns:
            self.sel.unregister(conn.sock)
            del self.conns[fd]
        conn.sock.close()
        if self.cycle_owner is conn:
            self.cycle_owner = None

    def flush(self, conn: Conn, now: float) -> None:
        while conn.pieces and conn.pieces[0][0] <= now:
            due, piece = conn.pieces[0]
            try:
                sent = conn.sock.send(piece)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return self.drop(conn)
            if sent < len(piece):
                conn.pieces[0] = (due, piece[sent:])
                return
            conn.pieces.pop(0)
        if conn.closing and not conn.pieces:
            self.drop(conn)

    def serve(self, lsock: socket.socket) -> None:
        lsock.setblocking(False)
        self.sel.register(lsock, selectors.EVENT_READ, None)
        while True:
            now = time.monotonic()
            dues = [c.pieces[0][0] for c in self.conns.values() if c.pieces]
            timeout = max(0.0, min(dues) - now) if dues else 1.0
            for key, _ in self.sel.select(timeout):
                if key.data is None:
                    self.accept(lsock)
                else:
                    self.read(key.data)
            now = time.monotonic()
            for conn in list(self.conns.values()):
                if conn.pieces or conn.closing:
                    self.flush(conn, now)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.impls.selectbox", description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--config", choices=sorted(CONFIGS), default="a5err")
    parser.add_argument("--seed", type=int, default=None)
    args = parser.parse_args(argv)
    lsock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    lsock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    lsock.bind(("127.0.0.1", args.port))
    lsock.listen(512)
    print(f"listening tcp 127.0.0.1:{lsock.getsockname()[1]}", flush=True)
    try:
        Box(CONFIGS[args.config], random.Random(args.seed)).serve(lsock)
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
