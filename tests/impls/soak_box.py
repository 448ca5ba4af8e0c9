"""Boxes for the soak: legal ones, and ones that fail only over time (issue 38).

``python -m tests.impls.soak_box NAME --port 0`` serves one on 127.0.0.1 (first stdout line:
``listening tcp 127.0.0.1:PORT``) until SIGTERM/SIGINT. Written with ``struct`` and asyncio from
PROTOCOL.md (the frame: :mod:`tests.impls.wire_format`), no suite code. Each defect is small and
slow, as on a plant:

* ``flat``: legal, answers at once;
* ``slow``: legal, every answer 40 ms late (well inside time_out);
* ``stalling``: legal, every 4th session's answers held 600 ms (inside time_out), then resumed;
* ``one-cycle``: legal, one cycle for the whole box: CycleOn while it runs is 0001 (not ready), CycleOff
  while none runs is 0002 (S3); a robot that vanishes mid-cycle leaves it running;
* ``leak-rss``: keeps 256 KiB per connection it ever accepted (RSS grows per session);
* ``latency-creep``: every answer is 0.5 ms later per session served before it (T2);
* ``fd-leak``: never closes a connection the robot closed (CLOSE_WAIT: descriptors grow, S5);
* ``stop-after``: stops accepting after 12 sessions (S5 FAIL with N);
* ``dies-after``: after 10 sessions it prints ``fatal: session table full`` and exits 70;
* ``half-open-cap``: at most 6 connections, no idle time-out: a robot that vanishes holds its
  slots forever, and the box stops serving once the abandoned connections fill them (R5).
"""

from __future__ import annotations

import argparse
import asyncio
import os
import signal
import struct
import sys
from dataclasses import dataclass

from .wire_format import BOX_TO_ROBOT, CYCLE_OFF, CYCLE_ON, HEADER, HEADER_LEN, PROG_IDX, RESULT

CHECK = b"\x00\x00"


@dataclass(frozen=True)
class Knobs:
    delay_ms: float = 0.0
    stall_every: int = 0
    stall_ms: float = 0.0
    leak_kib: int = 0
    creep_ms: float = 0.0
    fd_leak: bool = False
    stop_after: int = 0
    max_conns: int = 0
    die_after: int = 0
    one_cycle: bool = False


BOXES: dict[str, Knobs] = {
    "flat": Knobs(),
    "slow": Knobs(delay_ms=40.0),
    "stalling": Knobs(stall_every=4, stall_ms=600.0),
    "one-cycle": Knobs(one_cycle=True),
    "leak-rss": Knobs(leak_kib=256),
    "latency-creep": Knobs(creep_ms=0.5),
    "fd-leak": Knobs(fd_leak=True),
    "stop-after": Knobs(stop_after=12),
    "half-open-cap": Knobs(max_conns=6),
    "dies-after": Knobs(die_after=10),
}
LEGAL = ("flat", "slow", "stalling", "one-cycle")


def answer_for(header: tuple[int, ...], body: bytes, error: int = 0) -> bytes:
    """The answer to one well-formed request (action echoed, ``error``; 26 echoes its index, 27 answers OK)."""
    action = header[3]
    if action == PROG_IDX and len(body) >= 5:
        return HEADER.pack(0xFEFE, 1, BOX_TO_ROBOT, action, 3, 1, 5, 0) + body[:5] + CHECK
    if action == RESULT:
        return HEADER.pack(0xFEFE, 1, BOX_TO_ROBOT, action, 3, 1, 5, 0) + b"\x00" + struct.pack(">i", 1) + CHECK
    return HEADER.pack(0xFEFE, 1, BOX_TO_ROBOT, action, 0, 0, 0, error) + CHECK


class SoakBox:
    def __init__(self, knobs: Knobs) -> None:
        self.knobs = knobs
        self.sessions = 0  # command connections seen (the first frame on them is not a pose)
        self.open = 0
        self.kept: list[bytearray] = []
        self.leaked: list[asyncio.StreamWriter] = []
        self.server: asyncio.AbstractServer | None = None
        self.cycle = False  # one-cycle: a cycle runs on the box

    def cycle_error(self, action: int) -> int:
        """one-cycle: 0001 to CycleOn while a cycle runs, 0002 to CycleOff while none does; else 0000."""
        if not self.knobs.one_cycle or action not in (CYCLE_ON, CYCLE_OFF):
            return 0
        if action == CYCLE_ON:
            if self.cycle:
                return 0x0001
            self.cycle = True
            return 0
        if not self.cycle:
            return 0x0002
        self.cycle = False
        return 0

    async def serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        knobs = self.knobs
        if knobs.max_conns and self.open >= knobs.max_conns:
            writer.close()  # full: the robot is turned away
            return
        if knobs.stop_after and self.sessions >= knobs.stop_after:
            writer.close()
            return
        self.open += 1
        if knobs.leak_kib:
            self.kept.append(bytearray(b"\x5a" * (knobs.leak_kib * 1024)))
        session = None
        poses = 0
        loop = asyncio.get_running_loop()
        try:
            while True:
                head = await reader.readexactly(HEADER_LEN)
                header = HEADER.unpack(head)
                body = await reader.readexactly(header[5] * header[6] + 2)
                if session is None:
                    session = self.sessions
                    if header[3] != 0x23:
                        self.sessions += 1  # a command connection: one more session
                        if knobs.die_after and self.sessions > knobs.die_after:
                            print("fatal: session table full", file=sys.stderr, flush=True)
                            os._exit(70)
                poses += header[3] == 0x23
                if knobs.stall_every and session % knobs.stall_every == knobs.stall_every - 1 and poses == 20:
                    await asyncio.sleep(knobs.stall_ms / 1000)  # one brief stall; the poses behind it queue
                delay = knobs.delay_ms + knobs.creep_ms * session
                data = answer_for(header, body, self.cycle_error(header[3]))
                if delay:  # the same delay for every answer of a connection: their order is kept
                    loop.call_later(delay / 1000, _write, writer, data)
                else:
                    writer.write(data)
        except (asyncio.IncompleteReadError, ConnectionError, struct.error):
            pass
        finally:
            if knobs.fd_leak:
                self.leaked.append(writer)  # never closed: CLOSE_WAIT, a descriptor per connection
            else:
                self.open -= 1
                writer.close()
            if knobs.stop_after and self.sessions >= knobs.stop_after and self.server is not None:
                self.server.close()  # stops accepting: later robots are refused


def _write(writer: asyncio.StreamWriter, data: bytes) -> None:
    if not writer.is_closing():
        writer.write(data)


async def main(name: str, port: int) -> None:
    box = SoakBox(BOXES[name])
    box.server = await asyncio.start_server(box.serve, "127.0.0.1", port)
    bound = box.server.sockets[0].getsockname()[1]
    print(f"listening tcp 127.0.0.1:{bound} box {name}", flush=True)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    await stop.wait()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("name", choices=sorted(BOXES))
    parser.add_argument("--port", type=int, default=0)
    args = parser.parse_args()
    asyncio.run(main(args.name, args.port))
    sys.exit(0)
