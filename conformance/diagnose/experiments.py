"""The live exchanges of the diagnose phase: each on a fresh connection, every wait bounded.

A :class:`Prober` sends frames in order on a new connection and reads what follows each one:
the first answer within the wait (the profile's time_out, cut to what is left of the phase's
deadline), then whatever else arrives within a short settle window (an extra answer written
with it). Nothing the box does raises out of here: a refused connection, a close, silence and
malformed bytes are all recorded in the :class:`~.hypotheses.Exchange`. Once the deadline has
passed no exchange is started (:meth:`Prober.exchange` returns None).

The request builders (:func:`valid_request`, :func:`block_request`) write the frames in the
run's profile (byte order, first index).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence, TcpConnection
from ..harness.connection import Dialer
from ..harness.target import Target, Unreachable
from ..harness.transcript import Transcript
from ..protocol import Action, PoseBlock, Profile, ToleranceBlock, Transport, codec_for, request
from ..protocol.constants import START_WORD
from .hypotheses import Exchange, Heard, Reading

#: after the first answer to a frame, keep reading this long for extras (within SETTLE_MIN_S..SETTLE_MAX_S,
#: SETTLE_PACE times the first answer's latency)
SETTLE_MIN_S = 0.05
SETTLE_MAX_S = 0.3
SETTLE_PACE = 4.0
#: the wait after a frame that may legally go unanswered (a parse error may be met with silence, A5/R6)
QUIET_S = 0.5
#: no exchange is started with less than this left before the deadline
MIN_LEFT_S = 0.25
POSE = (100.25, -200.5, 300.75, 0.0, 90.0, -180.0)


def heard(outcome: Answer | Malformed) -> Heard:
    if isinstance(outcome, Answer):
        f = outcome.frame
        return Heard(int(f.action), f.error_code, outcome.raw)
    h = outcome.error.header
    if h is None or h.start_word != START_WORD:
        return Heard(None, None, outcome.raw, str(outcome.error))
    return Heard(h.action, h.error_code, outcome.raw, str(outcome.error))


class Prober:
    """Fresh-connection exchanges with the box until ``deadline`` (time.monotonic())."""

    def __init__(self, target: Target, profile: Profile, time_out_s: float, deadline: float,
                 transcript: Transcript | None = None) -> None:
        self.profile = profile
        #: the connections: dialled fresh for each exchange, every wait time_out cut to what is left before the deadline
        self.dialer = Dialer(transcript if transcript is not None else Transcript(case_id="DIAGNOSE"), target, profile,
                             time_out_s, deadline)
        self.codec = codec_for(profile)
        self.count = 0  # exchanges made
        self.unreachable = ""  # why the last connection could not be made

    def left(self) -> float:
        return self.dialer.left()

    def _by(self, quiet: bool = False) -> float:
        """The deadline of the wait for an answer starting now (:data:`QUIET_S` at most for one that may not come)."""
        return time.monotonic() + min(QUIET_S, self.dialer.wait_s()) if quiet else self.dialer.by()

    def exchange(self, frames: Sequence[bytes], quiet: Sequence[bool] = (), settle: bool = True,
                 together: bool = False, stop_silent: bool = False) -> Exchange | None:
        """``frames`` in order on a fresh connection, reading after each (a ``quiet`` frame may go unanswered:
        its wait is :data:`QUIET_S`; ``settle`` False: after the first answer only what has already arrived is
        read, for experiments that count no extra answers). ``together``: all frames in one write (one
        segment, as a case that coalesced them sent them), then every answer in one reading; ``stop_silent``:
        no frame is sent after one went unanswered for the whole wait. None when the deadline leaves no room."""
        if self.left() < MIN_LEFT_S:
            return None
        self.count += 1
        try:
            conn = self.dialer.dial("diagnose")
        except Unreachable as exc:
            self.unreachable = str(exc)
            return Exchange(tuple(frames), (), reached=False)
        readings: list[Reading] = []
        try:
            if together:
                return Exchange(tuple(frames), (self._read_all(conn, b"".join(frames), len(frames)),), together=True)
            for i, frame in enumerate(frames):
                if not conn.send(frame, "diagnose"):
                    readings.append(Reading((), True))
                    break
                may_skip = i < len(quiet) and quiet[i]
                reading = self._read(conn, self._by(quiet=may_skip), settle)
                readings.append(reading)
                if reading.closed or (stop_silent and reading.silent and not may_skip):
                    break
        finally:
            conn.close("diagnose")
        return Exchange(tuple(frames), tuple(readings))

    def _read_all(self, conn: TcpConnection, data: bytes, count: int) -> Reading:
        """``data`` in one write; then answers until ``count`` came (and a settle window), a close, or silence."""
        if not conn.send(data, "diagnose"):
            return Reading((), True)
        got: list[Outcome] = []
        while len(got) < count + 4:
            outcome = conn.receive(self._by(quiet=bool(got)))
            if isinstance(outcome, Silence):
                break
            got.append(outcome)
            if isinstance(outcome, Closed):
                break
            if len(got) >= count:
                got += conn.drain(SETTLE_MIN_S)
                break
        answers = tuple(heard(o) for o in got if isinstance(o, (Answer, Malformed)))
        return Reading(answers, any(isinstance(o, Closed) for o in got))

    def _read(self, conn: TcpConnection, by: float, settle: bool = True) -> Reading:
        first = conn.receive(by)
        if isinstance(first, Silence):
            return Reading()
        if isinstance(first, Closed):
            return Reading((), True)
        window = min(SETTLE_MAX_S, max(SETTLE_MIN_S, SETTLE_PACE * first.latency_s))
        got: list[Outcome] = [first, *(conn.drain(window) if settle else conn.poll())]
        answers = tuple(heard(o) for o in got if isinstance(o, (Answer, Malformed)))
        return Reading(answers, any(isinstance(o, Closed) for o in got))

    # -- requests in the run's profile ----------------------------------------------------------------------
    def encode(self, frame_action: Action, blocks: Sequence[PoseBlock | ToleranceBlock] = ()) -> bytes:
        return self.codec.encode(request(frame_action, blocks), Transport.TCP)

    def valid_request(self, action: int) -> bytes:
        """A valid request of ``action`` with one block where it takes blocks."""
        return block_request(self, int(action), 1) if action in BLOCK_ACTIONS else self.encode(Action(action))


#: block actions and the length of their blocks (B1, B2, B5)
BLOCK_ACTIONS = {int(Action.POSE): 25, int(Action.REGISTER_POSE): 25, int(Action.TOLERANCE): 5}


def block_request(prober: Prober, action: int, count: int, wrong_at: int | None = None, value: int = 0) -> bytes:
    """A request of ``action`` with ``count`` blocks, indexes rising from the profile's first index, except
    ``value`` at 0-based position ``wrong_at``."""
    first = prober.profile.first_index
    blocks: list[PoseBlock | ToleranceBlock] = []
    for i in range(count):
        index = value if i == wrong_at else (first + i) & 0xFF
        blocks.append(ToleranceBlock(index, 0.5) if action == Action.TOLERANCE else PoseBlock(index, POSE))
    return prober.encode(Action(action), blocks)
