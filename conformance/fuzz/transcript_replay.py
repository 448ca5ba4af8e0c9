"""Replaying what a session sent, connection by connection, to confirm that it kills the box (R2).

A session of the state machine that left the box dead is not shrunk (every step would
need a restart); it is *confirmed* instead: after the box is brought back, every
connection the session opened is opened again in the same order, every write is
written again, and before each next step the replay waits until the box has sent as
many bytes on that connection as it did the first time, or closes it where it did
(bounded by time_out). The liveness checks of the original run are left out. Then a fresh connection tells
whether the box died again.
"""

from __future__ import annotations

from ..harness.client import Closed, Silence, TcpConnection
from ..harness.target import Target, Unreachable
from ..harness.transcript import Kind, Transcript
from ..protocol import Profile

#: Connections with these labels are the suite's own checks, not the session's traffic.
CHECK_LABELS = ("liveness",)


def _wait_for(conn: TcpConnection, want: int, time_out_s: float) -> None:
    """Read until the box has sent ``want`` bytes on ``conn`` (or closed it, or time_out passed)."""
    while conn.received_bytes < want and conn.closed_by_peer is None:
        if isinstance(conn.next_outcome(time_out_s), (Closed, Silence)):
            return


def replay_sends(original: Transcript, profile: Profile, into: Transcript, time_out_s: float | None = None) -> int:
    """Replay ``original``'s connections and writes (see the module docstring); the writes replayed."""
    wait = time_out_s if time_out_s is not None else profile.time_out_s
    infos = dict(original.connections)
    conns: dict[int, TcpConnection] = {}
    want: dict[int, int] = {}
    sent, last = 0, None
    try:
        for ev in list(original.events):
            info = infos.get(ev.conn)
            if info is None or info.transport != "tcp" or any(lbl in info.label for lbl in CHECK_LABELS):
                continue
            conn = conns.get(ev.conn)
            if ev.kind == Kind.CONNECT:
                conn = conns[ev.conn] = TcpConnection(into, Target(info.remote.host, info.remote.port), profile,
                                                      f"replay: {info.label}", wait)
                try:
                    conn.connect()
                except Unreachable:
                    return sent
                want[ev.conn] = 0
            elif conn is None:
                continue
            elif ev.kind == Kind.SEND:
                conn.send(ev.data, f"replayed: {ev.note}"[:200])
                sent, last = sent + 1, ev.conn
            elif ev.kind == Kind.RECV:
                want[ev.conn] += len(ev.data)
                _wait_for(conn, want[ev.conn], wait)
            elif ev.kind in (Kind.PEER_CLOSE, Kind.PEER_RESET):  # the box closed it here: wait for it to do so again
                _wait_for(conn, 1 << 62, wait)
            elif ev.kind == Kind.CLOSE:
                conn.close("replayed close")
            elif ev.kind == Kind.ABORT:
                conn.abort("replayed reset")
        if last is not None:  # what the last write did: the box closes as it dies (or the wait runs out)
            _wait_for(conns[last], want[last] + 1, wait)
    finally:
        for conn in conns.values():
            conn.abort("replay done")
    return sent


__all__ = ["CHECK_LABELS", "replay_sends"]
