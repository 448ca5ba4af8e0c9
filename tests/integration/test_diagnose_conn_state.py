"""The connection-state experiments against three small loopback boxes served in this process: one that closes a
connection idle for 0.6 s, one that closes every connection 0.8 s after it opened, one that closes the older
connection when a new one opens. Each must be told apart from the other two by its own experiment."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

from conformance.diagnose import conn_peers, conn_state
from conformance.diagnose.experiments import Prober
from conformance.harness.target import Target
from conformance.protocol import Profile


class _Box:
    """Answers every 14-byte request 0000 (its action echoed); closes connections as ``how`` says."""

    def __init__(self, how: str) -> None:
        self.how = how
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.conns: list[socket.socket] = []
        self.stop = threading.Event()

    def serve(self) -> None:
        self.server.settimeout(0.1)
        while not self.stop.is_set():
            try:
                sock, _ = self.server.accept()
            except TimeoutError:
                continue
            if self.how == "newest":
                for old in self.conns:
                    old.close()
            self.conns.append(sock)
            threading.Thread(target=self.one, args=(sock, time.monotonic()), daemon=True).start()

    def one(self, sock: socket.socket, opened: float) -> None:
        buf = b""
        sock.settimeout(0.05)
        last = time.monotonic()
        try:
            while not self.stop.is_set():
                now = time.monotonic()
                if (self.how == "idle" and now - last > 0.6) or (self.how == "age" and now - opened > 0.8):
                    break
                try:
                    data = sock.recv(4096)
                except TimeoutError:
                    continue
                if not data:
                    break
                buf, last = buf + data, now
                while len(buf) >= 14:
                    frame, buf = bytearray(buf[:14]), buf[14:]
                    frame[4] = 0x10
                    sock.sendall(bytes(frame))
        except OSError:
            pass
        finally:
            sock.close()


@contextmanager
def serving(how: str) -> Iterator[_Box]:
    box = _Box(how)
    thread = threading.Thread(target=box.serve, daemon=True)
    thread.start()
    try:
        yield box
    finally:
        box.stop.set()
        thread.join(2)
        box.server.close()


def test_idle_age_and_a_new_connection_are_told_apart() -> None:
    profile = Profile().replace(time_out_ms=1000)
    found = {}
    for how in ("idle", "age", "newest"):
        with serving(how) as box:
            p = Prober(Target("127.0.0.1", box.port), profile, 1.0, time.monotonic() + 12.0)
            peers = conn_peers.run(p)
            state = conn_state.run(p, None, None) if not conn_peers.decided(peers) else None
            found[how] = (peers, state)
    idle_peers, idle = found["idle"]
    assert not conn_peers.decided(idle_peers) and idle is not None
    assert [m.kind for m in idle.mechanisms] == ["idle-close"], idle.stories
    assert 0.4 < idle.mechanisms[0].detail["idle_s"] < 2.0
    age_peers, age = found["age"]
    assert age is not None and [m.kind for m in age.mechanisms] == ["age-close"], age.stories
    newest, none = found["newest"]
    assert none is None and [m.detail["after"] for m in newest.mechanisms] == [0]
