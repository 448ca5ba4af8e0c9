"""A box for the time-to-bug benchmark: an iSight AI Box of its own, with one planted deep defect at a time.

Written from PROTOCOL.md alone (threads and blocking sockets; it shares no code with
``conformance/`` or ``tests/impls``). Without ``--defect`` it is a conforming box: the
benchmark's false-alarm check. With ``--defect NAME`` one defect of :data:`DEFECTS`
is planted; when it fires the box appends a line to ``--fired FILE`` (the benchmark
counts a finding only if the defect fired before it).

    python benchmarks/ttb_box.py --port 9100 --defect count7-crash --fired /tmp/f [--udp]
    python benchmarks/ttb_box.py --port 9100 --defect count7-crash --restart --pidfile /tmp/p   # a restart command

Framing: a header whose start word and version are right is trusted (its announced
length skipped as one frame; more than the largest legal frame closes the connection);
otherwise the box resynchronises at the next FE FE (R6 (a), (b), (c)).
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

#: name -> what it does (the benchmark's table lists them in this order).
DEFECTS = {
    "count7-crash": "crash on a well-formed tolerance request with exactly 7 blocks",
    "count200-hang": "hang on a well-formed pose request with 200-254 blocks",
    "negzero-wrong": "answer 1002 to a tolerance of -0.0 (legal: 0000)",
    "subnormal-crash": "crash on a pose holding a subnormal float",
    "nanpayload-crash": "crash on a NaN with a payload other than the default quiet NaN",
    "huge-hang": "hang on a register pose with a magnitude >= 1e30",
    "errfield-crash": "crash on a request whose error field is >= 0x8000",
    "sequence-hang": "hang on a register pose right after CycleOff on the same connection",
    "cycle-wrong": "answer 0001 to CycleOff of a cycle that received a tolerance (allowed: 0000/0002)",
    "split-crash": "crash when a read returns exactly the first 7 bytes of a frame",
    "pause-drop": "drop a partial frame after a pause of 100 ms mid-frame (the request goes unanswered)",
    "many-crash": "crash when 8 connections are open at once",
    "reconnect-dies": "stop accepting after 20 connections closed without a byte within 2 s",
    "udp-wrong": "answer 0000 to a UDP datagram with a wrong CRC",
}

KNOWN = {0x00, 0x01, 0x02, 0x23, 0x24, 0x25, 0x26, 0x27}
SHAPE = {0x00: (0, 0, 0, 0), 0x01: (0, 0, 0, 0), 0x02: (0, 0, 0, 0), 0x27: (0, 0, 0, 0),
         0x23: (1, 1, 255, 25), 0x24: (1, 1, 255, 25), 0x25: (2, 1, 255, 5), 0x26: (3, 1, 1, 5)}
MAX_BODY = 255 * 25


def crc16(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


class Hang(Exception):
    """The connection stops answering (a planted hang)."""


class Box:
    def __init__(self, defect: str, fired: Path | None) -> None:
        self.defect = defect
        self.fired_path = fired
        self.lock = threading.Lock()
        self.cycle_on = False
        self.tolerance_in_cycle = False
        self.open_conns = 0
        self.silent_closes: list[float] = []
        self.server: socket.socket | None = None

    # -- defects ---------------------------------------------------------------------------
    def fire(self, what: str) -> None:
        if self.fired_path is not None:
            with open(self.fired_path, "a", encoding="utf-8") as f:
                f.write(f"{time.time():.3f} {self.defect} {what}\n")

    def crash(self, what: str) -> None:
        self.fire(what)
        os._exit(3)

    # -- frames ----------------------------------------------------------------------------
    def answer(self, action: int, error: int = 0, value: int | None = None, udp: bool = False) -> bytes:
        if value is None:
            data = struct.pack(">HHBBBBHH", 0xFEFE, 1, 0x10, action, 0, 0, 0, error)
        else:
            data = struct.pack(">HHBBBBHHBi", 0xFEFE, 1, 0x10, action, 3, 1, 5, error, 0, value)
        return data + (crc16(data).to_bytes(2, "big") if udp else b"\0\0")

    def handle(self, frame: bytes, last: list[int], udp: bool = False) -> bytes | None:
        """The answer to one frame (None: silence); ``last[0]``: the previous request's action on the connection."""
        tt, action, bt, n, length, error = struct.unpack_from(">BBBBHH", frame, 4)
        if tt != 0x01 or action not in KNOWN:
            return None
        d = self.defect
        if d == "errfield-crash" and error >= 0x8000:
            self.crash(f"error field {error:#06x}")
        want_bt, low, high, want_len = SHAPE[action]
        body = frame[12:-2]
        bad = (bt, length) != (want_bt, want_len) or not low <= n <= high
        floats: list[int] = []
        if not bad:
            for i in range(n):
                block = body[i * length : (i + 1) * length]
                bad = bad or block[0] != i
                if bt in (1, 2):
                    floats += [int.from_bytes(block[j : j + 4], "big") for j in range(1, length, 4)]
        if d == "nanpayload-crash" and any((b & 0x7F800000) == 0x7F800000 and b & 0x7FFFFF not in (0, 0x400000)
                                           for b in floats):
            self.crash("a NaN with a payload")
        bad = bad or any((b & 0x7F800000) == 0x7F800000 for b in floats)
        prev, last[0] = last[0], action
        if bad:
            return self.answer(action, 0x1002 if action == 0x25 else 0x1001, udp=udp)
        return self.valid(action, n, floats, body, prev, udp)

    def valid(self, action: int, n: int, floats: list[int], body: bytes, prev: int, udp: bool) -> bytes | None:
        d = self.defect
        if d == "count7-crash" and action == 0x25 and n == 7:
            self.crash("tolerance x7")
        if d == "count200-hang" and action == 0x23 and 200 <= n <= 254:
            self.fire(f"pose x{n}")
            raise Hang
        if d == "subnormal-crash" and action == 0x23 and any(b & 0x7F800000 == 0 and b & 0x7FFFFF for b in floats):
            self.crash("subnormal pose")
        if d == "huge-hang" and action == 0x24 and any(b & 0x7F800000 >= 0x71000000 for b in floats):
            self.fire("huge register pose")
            raise Hang
        if d == "sequence-hang" and action == 0x24 and prev == 0x02:
            self.fire("register pose after CycleOff")
            raise Hang
        if d == "negzero-wrong" and action == 0x25 and 0x80000000 in floats:
            self.fire("tolerance -0.0")
            return self.answer(action, 0x1002, udp=udp)
        with self.lock:
            if action == 0x01:
                self.cycle_on, self.tolerance_in_cycle = True, False
            elif action == 0x02:
                wrong = d == "cycle-wrong" and self.cycle_on and self.tolerance_in_cycle
                self.cycle_on = False
                if wrong:
                    self.fire("CycleOff after a tolerance")
                    return self.answer(action, 0x0001, udp=udp)
            elif action == 0x25 and self.cycle_on:
                self.tolerance_in_cycle = True
        if action == 0x26:
            return self.answer(action, 0, struct.unpack(">i", body[1:5])[0], udp)
        if action == 0x27:
            return self.answer(action, 0, 1, udp)
        return self.answer(action, udp=udp)

    # -- connections -------------------------------------------------------------------------
    def serve(self, conn: socket.socket) -> None:
        with self.lock:
            self.open_conns += 1
            many = self.defect == "many-crash" and self.open_conns >= 8
        if many:
            self.crash("8 connections at once")
        got_any = False
        try:
            got_any = self._loop(conn)
        except (OSError, Hang):
            pass
        finally:
            with self.lock:
                self.open_conns -= 1
            if not got_any:
                self._silent_close()
            conn.close()

    def _silent_close(self) -> None:
        if self.defect != "reconnect-dies":
            return
        now = time.monotonic()
        with self.lock:
            self.silent_closes = [t for t in self.silent_closes if now - t < 2.0] + [now]
            dies = len(self.silent_closes) >= 20
        if dies and self.server is not None:
            self.fire("20 quick reconnects")
            try:
                self.server.shutdown(socket.SHUT_RDWR)  # wakes the accept loop: the box stops listening
            except OSError:
                pass
            self.server.close()

    def _loop(self, conn: socket.socket) -> bool:
        buf = b""
        last = [-1]
        got_any = False
        conn.settimeout(0.1 if self.defect == "pause-drop" else None)
        while True:
            try:
                data = conn.recv(65536)
            except TimeoutError:
                if buf:
                    self.fire("pause mid-frame")
                    buf = b""
                continue
            if not data:
                return got_any
            got_any = True
            if self.defect == "split-crash" and not buf and len(data) == 7 and data[:2] == b"\xfe\xfe":
                self.crash("7-byte piece")
            buf += data
            buf, frames, close = split(buf)
            for frame in frames:
                try:
                    out = self.handle(frame, last)
                except Hang:
                    while conn.recv(65536):  # silent from now on, until the robot gives up
                        pass
                    return got_any
                if out is not None:
                    conn.sendall(out)
            if close:
                return got_any

    def datagram(self, sock: socket.socket) -> None:
        while True:
            data, peer = sock.recvfrom(65536)
            if len(data) < 14:
                continue
            n, length = data[7], int.from_bytes(data[8:10], "big")
            if data[:4] != b"\xfe\xfe\x00\x01" or len(data) != 14 + n * length:
                continue
            if int.from_bytes(data[-2:], "big") != crc16(data[:-2]):
                if self.defect == "udp-wrong":
                    self.fire("wrong CRC answered")
                    sock.sendto(self.answer(data[5], udp=True), peer)
                continue
            try:
                out = self.handle(data, [-1], udp=True)
            except Hang:
                continue
            if out is not None:
                sock.sendto(out, peer)


def split(buf: bytes) -> tuple[bytes, list[bytes], bool]:
    """(the rest, whole frames, close the connection) of a TCP buffer."""
    frames: list[bytes] = []
    while len(buf) >= 2:
        if buf[:2] != b"\xfe\xfe":
            i = buf.find(b"\xfe\xfe", 1)
            buf = buf[i:] if i >= 0 else buf[-1:] if buf[-1:] == b"\xfe" else b""
            continue
        if len(buf) < 12:
            break
        if buf[2:4] != b"\x00\x01":
            buf = buf[1:]
            continue
        size = buf[7] * int.from_bytes(buf[8:10], "big")
        if size > MAX_BODY:
            return b"", frames, True
        if len(buf) < 14 + size:
            break
        frames.append(buf[: 14 + size])
        buf = buf[14 + size :]
    return buf, frames, False


def serve(port: int, defect: str, fired: Path | None, udp: bool) -> None:
    box = Box(defect, fired)
    server = box.server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", port))
    server.listen(64)
    if udp:
        u = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        u.bind(("127.0.0.1", server.getsockname()[1]))
        threading.Thread(target=box.datagram, args=(u,), daemon=True).start()
    print(f"listening {server.getsockname()[1]}", flush=True)
    while True:
        try:
            conn, _ = server.accept()
        except OSError:
            time.sleep(3600)  # no longer accepting (reconnect-dies): the process stays, dead to new robots
            continue
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        threading.Thread(target=box.serve, args=(conn,), daemon=True).start()


def restart(args: argparse.Namespace) -> int:
    """Kill the box of ``--pidfile`` (if any), start a new one in the background, wait until it answers."""
    pidfile = Path(args.pidfile)
    try:
        os.kill(int(pidfile.read_text()), signal.SIGKILL)
    except (OSError, ValueError):
        pass
    cmd = [sys.executable, __file__, "--port", str(args.port), "--defect", args.defect]
    cmd += ["--fired", args.fired] if args.fired else []
    cmd += ["--udp"] if args.udp else []
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    pidfile.write_text(str(proc.pid))
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", args.port), timeout=1).close()
            return 0
        except OSError:
            time.sleep(0.05)
    return 1


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--port", type=int, default=0)
    p.add_argument("--defect", default="clean", choices=["clean", *DEFECTS])
    p.add_argument("--fired", help="append a line to this file when the defect fires")
    p.add_argument("--udp", action="store_true", help="also serve UDP on the same port number")
    p.add_argument("--restart", action="store_true", help="restart the box of --pidfile in the background")
    p.add_argument("--pidfile")
    args = p.parse_args(argv)
    if args.restart:
        return restart(args)
    serve(args.port, args.defect, Path(args.fired) if args.fired else None, args.udp)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
