"""One probed exchange: bytes, a probe behind them, what the box sent back, attributed.

The catalogue (:meth:`conformance.suite.case_context.CaseContext.send_malformed`), the
fuzzer (:class:`conformance.fuzz.executor.Executor`) and ``replay`` all send some
bytes followed by a valid *probe* request. Answers come in order (A1), so the probe's
answer bounds the wait without sleeping. This module is what they share:

* **the probe** (:func:`choose_probe`): a request answered 0000 in any cycle state,
  whose action no frame in the bytes has under any legal framing (R6 lets a receiver
  resume at any start word, :func:`~conformance.protocol.framings.embedded_actions`)
  and no request of the case has. When every candidate is taken there is no probe
  (None): the exchange then waits time_out, which is bounded, rather than end the wait
  at an answer that may not be the probe's;
* **send and collect** (:func:`collect`): everything the box sends until an answer
  with the probe's action, a close, or silence for time_out;
* **the settle window** (:class:`Settle`): after that answer, how long to keep reading
  for extras written with it (an answer nobody asked for, A1; a close);
* **attribution** (:func:`attribute`): every answer is matched to the bytes some legal
  framing makes it answer (:mod:`conformance.protocol.explain`), so the probe's own
  (even malformed) answer is never taken for an answer to the bytes.

Liveness (R2) is :mod:`.liveness`.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Iterable
from dataclasses import dataclass, field

from ..protocol import (
    EXTENSION_ACTIONS,
    HEADER_LEN,
    Action,
    AnswerError,
    Frame,
    Profile,
    UnknownActionError,
    pose_blocks,
    request,
    tolerance_blocks,
)
from ..protocol.answers import Seen
from ..protocol.constants import START_WORD
from ..protocol.explain import explain
from ..protocol.framings import End, Explanation, embedded_actions
from .client import MAX_DRAIN, Answer, Closed, Malformed, Outcome, Silence, TcpConnection

#: Probes, in order of preference: each is answered 0000 in any cycle state (A4, B1, S3).
PROBE_ACTIONS = (Action.NONE, Action.POSE, Action.TOLERANCE, Action.REGISTER_POSE)
PROBE_POSE_VALUES = (100.25, -200.5, 300.75, 0.0, 90.0, -180.0)

#: The settle window's bounds: at least SETTLE_FLOOR_S, at most SETTLE_S (see :class:`Settle`).
SETTLE_FLOOR_S = 0.005
SETTLE_S = 0.05
#: ... and in between, this many times the latency of the probe's answer (the box's own pace).
SETTLE_PACE = 4.0


def probe_pose(profile: Profile) -> Frame:
    """A valid pose request in this profile (its first index)."""
    return request(Action.POSE, pose_blocks([PROBE_POSE_VALUES], profile.first_index))


def probe_request(action: Action, profile: Profile) -> Frame:
    """The probe request with this action (one of :data:`PROBE_ACTIONS`)."""
    if action is Action.POSE:
        return probe_pose(profile)
    if action is Action.TOLERANCE:
        return request(Action.TOLERANCE, tolerance_blocks([0.5], profile.first_index))
    if action is Action.REGISTER_POSE:
        return request(Action.REGISTER_POSE, probe_pose(profile).blocks)
    assert action is Action.NONE, action
    return request(Action.NONE)


def choose_probe(data: bytes, used: Iterable[int] = ()) -> Action | None:
    """The first probe action that neither a frame some legal framing finds in ``data`` nor a
    request of the case (``used``) has; None when every candidate is taken (then send no probe)."""
    taken = set(used) | embedded_actions(data)
    return next((a for a in PROBE_ACTIONS if a not in taken), None)


@dataclass(frozen=True)
class Settle:
    """How long to keep reading after the first answer with the probe's action.

    After a 0000 answer: ``pace`` times its latency, within ``floor_s``..``cap_s`` (an
    extra answer written with it trails it by about the box's own pace: a fast box costs
    ``floor_s`` per exchange, a slow or descheduled one gets up to ``cap_s``); ``floor_s``
    0 takes only what has already arrived. After an answer with an error (it may be a
    refusal of the bytes, A5, with the probe's 0000 answer still to come): ``cap_s``. An
    answer already begun when the window closes is read to its end (within time_out)."""

    floor_s: float = SETTLE_FLOOR_S
    cap_s: float = SETTLE_S
    pace: float = SETTLE_PACE

    @classmethod
    def fixed(cls, seconds: float) -> Settle:
        return cls(seconds, seconds, 0.0)

    def window(self, latency_s: float, ambiguous: bool) -> float:
        if ambiguous:
            return max(self.cap_s, self.floor_s)
        return min(self.cap_s, max(self.floor_s, self.pace * latency_s))


def action_of(outcome: Outcome) -> int | None:
    """The action byte of what the box sent: an answer, or malformed bytes with a readable header."""
    if isinstance(outcome, Answer):
        return int(outcome.frame.action)
    header = outcome.error.header if isinstance(outcome, Malformed) else None
    return header.action if header is not None and header.start_word == START_WORD else None


def error_code(outcome: Outcome | None) -> int | None:
    """The error code of what the box sent: an answer, or malformed bytes with a readable header."""
    if isinstance(outcome, Answer):
        return outcome.frame.error_code
    header = outcome.error.header if isinstance(outcome, Malformed) else None
    return header.error_code if header is not None and header.start_word == START_WORD else None


def answers_zero(outcome: Outcome, action: int) -> bool:
    """A well-formed 0000 answer with this action."""
    return isinstance(outcome, Answer) and outcome.frame.action == action and outcome.frame.error_code == 0


@dataclass
class Collected:
    """What the box sent for one probed exchange."""

    outcomes: list[Outcome] = field(default_factory=list)  # the answers before the probe's, and late extras
    end: Outcome | None = None  # the answer with the probe's action (the probe's), a Closed or a Silence
    close: Closed | None = None  # a close or reset that came in the settle window
    #: the probe's action came with an error and the wait for its 0000 behind it ran out (the wait's bound)
    ran_out: bool = False

    @property
    def probe_answered(self) -> bool:
        """An answer with the probe's action ended the wait (attribution says whose it is)."""
        return isinstance(self.end, (Answer, Malformed))

    @property
    def usable(self) -> bool:
        """The connection can take another exchange (not closed, reset or hung)."""
        return self.probe_answered and self.close is None

    @property
    def kind(self) -> End:
        """How the exchange ended, for attribution. A close after a 0000 answer with the probe's
        action came after everything was answered; after an answer with an error it may have
        followed a refusal of the bytes (A5, R6(c)) with the probe never read: CLOSED."""
        if isinstance(self.end, Closed) or (self.close is not None and not self._probe_zero()):
            return End.CLOSED
        return End.SILENT if isinstance(self.end, Silence) else End.ANSWERED

    def _probe_zero(self) -> bool:
        return isinstance(self.end, Answer) and self.end.frame.error_code == 0

    def answers(self) -> list[Answer | Malformed]:
        """Every answer in order, the probe's (``end``) last."""
        out = [o for o in self.outcomes if isinstance(o, (Answer, Malformed))]
        return out + [self.end] if isinstance(self.end, (Answer, Malformed)) else out


def send_and_collect(conn: TcpConnection, data: bytes, probe: int | None, probe_bytes: bytes, note: str,
                     settle: Settle, timeout_s: float | None = None, splits: tuple[int, ...] = (),
                     gap_s: float = 0.0, await_s: float | None = None) -> Collected:
    """``data`` and the probe behind it in one write (the box sees them as one segment, every time:
    R4 requires it to answer both), or cut at the offsets ``splits`` with ``gap_s`` between the
    pieces (R3), then :func:`collect`. If the write fails, what had already arrived and the close."""
    start = time.monotonic()
    wire = data + probe_bytes
    cuts = [0, *splits, len(wire)]
    sent = conn.send_pieces([wire[a:b] for a, b in zip(cuts, cuts[1:]) if b > a], gap_s, note) if splits \
        else conn.send(wire, note)
    if not sent:
        arrived: list[Outcome] = [o for o in conn.poll() if not isinstance(o, Closed)]
        return Collected(arrived, conn.closed_by_peer or Closed(False, time.monotonic() - start))
    return collect(conn, probe, start, settle, timeout_s, await_s)


def collect(conn: TcpConnection, probe: int | None, start: float, settle: Settle,
            timeout_s: float | None = None, await_s: float | None = None) -> Collected:
    """Everything the box sends until an answer with the probe's action (then the settle
    window), a close, or silence (``timeout_s`` since ``start``; None: the connection's
    time_out, a wait that runs it out counted in the transcript). If a second answer with
    the probe's action follows the first at once and answers it 0000, the first answered
    the bytes (A5 lets a refusal carry any action) and the second is the probe's. ``await_s``: how long
    to wait for that 0000 (default ``timeout_s``; ``ran_out`` says it did not come)."""
    out = Collected()
    while len(out.outcomes) < MAX_DRAIN:
        outcome = conn.next_outcome(timeout_s, since=start)
        if isinstance(outcome, (Closed, Silence)):
            out.end = outcome
            return out
        if probe is None or action_of(outcome) != probe:
            out.outcomes.append(outcome)
            continue
        extra = _settle(conn, settle.window(outcome.latency_s, not answers_zero(outcome, probe)))
        if _maybe_refusal(outcome) and not answers_zero(outcome, probe):
            more = _await_probe(conn, probe, start, extra, timeout_s if await_s is None else await_s)
            out.ran_out = not any(isinstance(o, Closed) or answers_zero(o, probe) for o in extra + more)
            extra += more
        out.close = next((o for o in extra if isinstance(o, Closed)), None)
        extra = [o for o in extra if not isinstance(o, Closed)]
        late = next((k for k, o in enumerate(extra) if answers_zero(o, probe)), None)
        if late is not None:  # the first answered the bytes; what came between them too
            out.outcomes += [outcome, *extra[:late]]
            outcome = extra.pop(late)
            extra = extra[late:]
        out.outcomes += extra  # late extras: attribution sees them as answers nobody asked for
        out.end = outcome
        return out
    out.end = Silence(time.monotonic() - start)
    return out


def await_rest(conn: TcpConnection, probe: int, got: Collected, wait_s: float) -> Collected:
    """After a wait for the probe's 0000 that ran out at a short bound (``got.ran_out``): wait ``wait_s``
    more for it, and put what came where :func:`collect` would have (a late 0000 is the probe's answer,
    the error answer before it answered the bytes)."""
    more = _await_probe(conn, probe, time.monotonic(), [], wait_s)
    close = got.close or next((o for o in more if isinstance(o, Closed)), None)
    more = [o for o in more if not isinstance(o, Closed)]
    late = next((k for k, o in enumerate(more) if answers_zero(o, probe)), None)
    if late is None or got.end is None:
        return Collected(got.outcomes + more, got.end, close, ran_out=close is None)
    return Collected([*got.outcomes, got.end, *more[:late]] + more[late + 1:], more[late], close)


def _maybe_refusal(outcome: Outcome) -> bool:
    """A sound frame whose only fault, if any, is its error code: what a refusal of the bytes looks like.
    (An answer broken in its start word, version or direction is not waited on: a box whose every answer
    is broken that way would cost time_out per exchange.)"""
    return isinstance(outcome, Answer) or (isinstance(outcome, Malformed) and isinstance(outcome.error, AnswerError))


def _await_probe(conn: TcpConnection, probe: int, start: float, got: list[Outcome],
                 timeout_s: float | None) -> list[Outcome]:
    """After an error answer with the probe's action and its settle window: unless a close or a 0000
    with the probe's action came in the window, read on until one comes, or time_out since the probe
    was sent. A refusal of the bytes may carry the probe's action (A5), and the probe's own 0000 may
    trail it by anything up to time_out (T1): taking the refusal for the probe's answer left that 0000
    to be read as the answer to the next request on the connection (a false A1)."""
    if any(isinstance(o, Closed) or answers_zero(o, probe) for o in got):
        return []
    more: list[Outcome] = []
    deadline = start + (conn.time_out_s if timeout_s is None else timeout_s)
    while len(got) + len(more) < MAX_DRAIN:
        outcome = conn.next_outcome(max(0.0, deadline - time.monotonic()), since=start)
        if isinstance(outcome, Silence):
            break
        more.append(outcome)
        if isinstance(outcome, Closed) or answers_zero(outcome, probe):
            more += _settle(conn, 0.0) if not isinstance(outcome, Closed) else []
            break
    return more


def _settle(conn: TcpConnection, window_s: float) -> list[Outcome]:
    """What arrives within ``window_s``; then an answer already begun is read to its end."""
    extra = conn.drain(window_s) if window_s > 0 else conn.poll()
    if conn.decoder.buffered and not any(isinstance(o, Closed) for o in extra) and len(extra) < MAX_DRAIN:
        nxt = conn.next_outcome(conn.time_out_s)
        if not isinstance(nxt, Silence):
            extra.append(nxt)
    return extra


# -- attribution ---------------------------------------------------------------------------------


def seen_of(outcome: Answer | Malformed, profile: Profile) -> Seen:
    """An answer (or malformed bytes) from the box reduced to what attribution needs: its action
    byte, error code and block value when its header is readable, and what is wrong with it."""
    if isinstance(outcome, Answer):
        f = outcome.frame
        value = getattr(f.blocks[0], "value", None) if f.blocks else None
        return Seen(int(f.action), f.error_code, value, "", outcome.describe())
    err = outcome.error
    h = err.header
    if h is None or h.start_word != START_WORD:
        return Seen(None, None, None, err.clause, outcome.describe())
    value = None
    raw = err.raw
    if h.block_type == 3 and h.block_count >= 1 and len(raw) >= HEADER_LEN + 5:
        order = ">" if profile.float_byte_order == "big" else "<"
        value = struct.unpack_from(order + "i", raw, HEADER_LEN + 1)[0]
    # an answer whose only fault is its content (A4: NONE answered with an error; E3: 0 or 404) is
    # judged by its code and value, not as a malformed frame. So is a refusal: A5 lets a box answer a
    # non-request "with a non-zero error", and such an answer may echo an unknown action, or a 26/27
    # without the block only an accepted one carries (a well-formed 26/27 still needs its block: E2/E3
    # judge the value; an unknown action pairs with no request, which then goes unanswered: A1)
    refusal = h.error_code != 0 and (isinstance(err, UnknownActionError) or (
        err.clause in ("E2", "E3") and h.action in EXTENSION_ACTIONS and h.block_count == 0))
    problem = "" if isinstance(err, AnswerError) or refusal else err.clause
    return Seen(h.action, h.error_code, value, problem, outcome.describe())


def attribute(data: bytes, got: Collected, profile: Profile, *, extension: bool = True,
              probe_at: int | None = None) -> Explanation:
    """The legal framing of ``data`` (the probe's bytes included, from ``probe_at``) that best
    explains what the box sent (in order) and how the exchange ended."""
    seen = [seen_of(o, profile) for o in got.answers()]
    return explain(data, seen, got.kind, profile, extension=extension, probe_at=probe_at)
