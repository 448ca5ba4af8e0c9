"""A reference box that *dies* on a state sequence: the fuzzer's death-first tests (R2).

The behaviour is the reference box's (:class:`~conformance.endpoints.behaviour.BoxBehaviour`
behind the reference framing, on threads and blocking sockets), with one planted death:

* ``same``: a register pose right after CycleOff *on the same connection*;
* ``cross``: a pose on one connection right after CycleOff on *another* connection
  (the box's last request overall was that CycleOff);
* ``none``: no death (the clean box).

When it dies it raises an exception that nobody catches: Python prints the traceback
on stderr and the process exits (status 70), so no new connection is accepted.

    python tests/impls/dying_box.py --port 0 --death cross    # prints "listening PORT"
"""

from __future__ import annotations

import argparse
import os
import socket
import sys
import threading
import traceback
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from conformance.endpoints.behaviour import BoxBehaviour, BoxConfig, Decision  # noqa: E402
from conformance.protocol import Action, Frame, ProtocolError, StreamDecoder, TransferType, Transport  # noqa: E402

DEATHS = ("none", "same", "cross")


class PlantedDeath(RuntimeError):
    """The planted defect: the box's state machine meets a sequence it was never written for."""


class DyingBehaviour(BoxBehaviour):
    """The reference behaviour, watching the order of requests for the planted death."""

    def __init__(self, death: str) -> None:
        super().__init__(BoxConfig(extension=False))
        self.fast_path = False
        self.death = death
        self.lock = threading.Lock()
        self.last: tuple[int, Action] | None = None  # (connection, action) of the box's last request

    def decide_on(self, conn: int, event: Frame | ProtocolError, last_here: list[Action | None]) -> Decision:
        with self.lock:
            if isinstance(event, Frame):
                self._watch(conn, event.action, last_here[0])
                last_here[0] = event.action
                self.last = (conn, event.action)
            return self.decide(event, Transport.TCP)

    def _watch(self, conn: int, action: Action, last_here: Action | None) -> None:
        if self.death == "same" and action is Action.REGISTER_POSE and last_here is Action.CYCLE_OFF:
            raise PlantedDeath("register pose right after CycleOff on the same connection: the pose table is gone")
        if (self.death == "cross" and action is Action.POSE and self.last is not None
                and self.last[1] is Action.CYCLE_OFF and self.last[0] != conn):
            raise PlantedDeath("pose right after CycleOff on another connection: the cycle's buffers were freed")


def serve_connection(box: DyingBehaviour, conn: socket.socket, number: int) -> None:
    last_here: list[Action | None] = [None]
    decoder = StreamDecoder(box.profile, TransferType.ROBOT_TO_BOX)
    try:
        while True:
            data = conn.recv(65536)
            if not data:
                return
            out = b""
            for event in decoder.feed(data):
                decision = box.decide_on(number, event, last_here)
                if decision.close:
                    return
                out += decision.data(Transport.TCP) or b""
            if out:
                conn.sendall(out)
    except PlantedDeath:
        traceback.print_exc()
        sys.stderr.flush()
        os._exit(70)
    except OSError:
        return
    finally:
        conn.close()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--port", type=int, default=0)
    p.add_argument("--death", choices=DEATHS, default="none")
    args = p.parse_args(argv)
    box = DyingBehaviour(args.death)
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", args.port))
    server.listen(64)
    print(f"listening {server.getsockname()[1]}", flush=True)
    number = 0
    while True:
        conn, _ = server.accept()
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        number += 1
        threading.Thread(target=serve_connection, args=(box, conn, number), daemon=True).start()


if __name__ == "__main__":
    raise SystemExit(main())
