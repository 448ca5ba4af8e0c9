"""The peer of the time-to-bug benchmark: a boofuzz definition of the iSight protocol, headless.

Written from PROTOCOL.md the way a boofuzz user would: one request per action (start
word, version, transfer type, action, block type, count, length and error field as
big-endian ``s_word``/``s_byte`` primitives, one block with its index and float32 values
as ``s_dword`` bit patterns, the TCP check 00 00), and the session graph of the
canonical session (CycleOn -> tolerance -> CycleOff -> register pose ...), each test
case on a new connection. boofuzz does not judge answers; what it finds is a box that
dies: a watchdog checks every 50 ms that the box's process is alive (what boofuzz's
process monitor does) and a callback checks every 64 test cases that a fresh connection
is answered. The first death ends the run.

    python benchmarks/boofuzz_isight.py --port 9100 --duration 60 --result out.json

Needs ``pip install 'isight-conformance[bench]'`` (boofuzz); benchmark-only.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import socket
import struct
import tempfile
import threading
import time
from pathlib import Path

NONE = bytes.fromhex("fefe000101000000000000000000")


def alive(port: int) -> bool:
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=2.0) as s:
            s.settimeout(2.0)
            s.sendall(NONE)
            return len(s.recv(64)) > 0
    except OSError:
        return False


def define() -> dict[str, object]:
    """One boofuzz request per action; returns them by name."""
    from boofuzz import Request, s_block_end, s_block_start, s_byte, s_dword, s_get, s_initialize, s_static, s_word

    def frame(name: str, action: int, block_type: int, length: int, values: list[float]) -> None:
        s_initialize(name)
        s_word(0xFEFE, endian=">", name="start")
        s_word(0x0001, endian=">", name="version")
        s_byte(0x01, name="transfer_type")
        s_byte(action, name="action")
        s_byte(block_type, name="block_type")
        s_byte(1 if values else 0, name="block_count")
        s_word(length, endian=">", name="block_length")
        s_word(0, endian=">", name="error")
        if values and s_block_start("block"):
            s_byte(0, name="index")
            for i, v in enumerate(values):
                s_dword(struct.unpack(">I", struct.pack(">f", v))[0], endian=">", name=f"value{i}")
            s_block_end()
        s_static(b"\0\0", name="check")

    frame("none", 0x00, 0, 0, [])
    frame("cycle_on", 0x01, 0, 0, [])
    frame("cycle_off", 0x02, 0, 0, [])
    frame("pose", 0x23, 1, 25, [100.0, 200.0, 300.0, 0.0, 90.0, 0.0])
    frame("register", 0x24, 1, 25, [100.0, 200.0, 300.0, 0.0, 90.0, 0.0])
    frame("tolerance", 0x25, 2, 5, [0.5])
    names = ("none", "cycle_on", "cycle_off", "pose", "register", "tolerance")
    out: dict[str, Request] = {n: s_get(n) for n in names}
    return out  # type: ignore[return-value]


def process_alive(pidfile: str | None) -> bool:
    """What a process monitor tells boofuzz: is the box's process still there?"""
    if not pidfile:
        return True
    try:
        os.kill(int(Path(pidfile).read_text(encoding="utf-8")), 0)
        return True
    except (OSError, ValueError):
        return False


def run(port: int, duration: float, result: str, pidfile: str | None) -> None:
    from boofuzz import FuzzLoggerText, Session, Target, TCPSocketConnection

    started = time.monotonic()
    cases = [0]

    def finish(found: float | None, note: str) -> None:
        elapsed = time.monotonic() - started
        with open(result, "w", encoding="utf-8") as f:
            json.dump({"found_s": found, "note": note, "cases": cases[0], "seconds": round(elapsed, 2),
                       "cases_per_s": round(cases[0] / elapsed, 1) if elapsed else None}, f)
        os._exit(0)

    def check(target: object, fuzz_data_logger: object, session: object, *args: object, **kwargs: object) -> None:
        cases[0] += 1
        if cases[0] % 64 == 0 and not alive(port):
            finish(round(time.monotonic() - started, 3), "a fresh connection is not answered")

    def watchdog() -> None:
        """The process monitor: the box's process exiting is noticed at once, even while boofuzz retries."""
        while True:
            now = time.monotonic() - started
            if not process_alive(pidfile):
                finish(round(now, 3), "the box's process exited")
            if now > duration:
                finish(None, "budget spent")
            time.sleep(0.05)

    threading.Thread(target=watchdog, daemon=True).start()

    db = os.path.join(tempfile.mkdtemp(prefix="boofuzz-"), "boofuzz.db")
    session = Session(
        target=Target(connection=TCPSocketConnection("127.0.0.1", port, send_timeout=2.0, recv_timeout=0.02)),
        web_port=None, keep_web_open=False, fuzz_loggers=[FuzzLoggerText(file_handle=io.StringIO())],
        post_test_case_callbacks=[check], receive_data_after_each_request=True, db_filename=db,
        crash_threshold_request=10**6, crash_threshold_element=10**6, restart_sleep_time=0,
    )
    r = define()
    for name in ("none", "cycle_on", "cycle_off", "pose", "register", "tolerance"):
        session.connect(r[name])
    session.connect(r["cycle_on"], r["tolerance"])
    session.connect(r["tolerance"], r["cycle_off"])
    session.connect(r["cycle_off"], r["register"])
    session.connect(r["cycle_on"], r["pose"])
    session.fuzz()
    finish(None, "every mutation sent")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--result", required=True)
    p.add_argument("--pidfile", help="the box's pid (a process monitor); else only liveness every 64 cases")
    args = p.parse_args()
    run(args.port, args.duration, args.result, args.pidfile)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
