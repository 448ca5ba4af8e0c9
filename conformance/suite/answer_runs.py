"""A run of pipelined answers read in one go, judged against the requests (S6, A1, F5): what a backpressure
exchange sent and read (:class:`Backlog`), and the first thing wrong with its answers (:func:`judge_answers`),
naming where the first answer was lost when the requests' actions tell it (:func:`first_lost`). Sans-I/O.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from ..protocol import (
    ANSWER_SHAPE,
    Action,
    BlockType,
    Frame,
    ProtocolError,
    StreamDecoder,
    TransferType,
    answer,
    encode,
)
from ..protocol.constants import CHECK_LEN, HEADER_LEN

#: a blockless answer's length (F5: 12 + 0 + 2)
ANSWER_LEN = HEADER_LEN + CHECK_LEN
#: the actions whose answer carries no block (A2): their 0000 answers are ANSWER_LEN bytes
_BLOCKLESS = frozenset(int(a) for a, shape in ANSWER_SHAPE.items() if shape.block_type is BlockType.EMPTY)
#: how many bytes of the stream a finding quotes around the first bad answer
SHOWN = 48


@dataclass
class Backlog:
    """What a backpressure exchange sent and read."""

    requests: int = 0  # requests sent whole
    sent_bytes: int = 0
    received: bytearray = field(default_factory=bytearray)
    reads: int = 0  # recv() calls that returned data
    ended: str = ""  # "", "closed", "reset", "silent" (time_out with answers still due), "blocked" (sends stalled),
    # "budget" (answers still coming when BUDGET_S ran out: too slow a box to wait for, not a lost answer)
    unread_s: float = 0.0  # how long the suite read nothing at the start
    elapsed_s: float = 0.0
    pace_hz: float = 0.0  # answers per second to the pace probe (0: no probe)
    last_read_at: float = 0.0  # time.monotonic() of the last recv() that returned data
    first_read_at: float = 0.0  # ... and of the first


@dataclass(frozen=True)
class Verdict:
    """The first thing wrong with the answers (None fields: all well)."""

    clause: str  # F5 (cut short / malformed), A1 (wrong, out of order, missing or extra), S6 (lost)
    expected: str
    observed: str
    received: bytes = b""
    #: only fewer answers than requests, every one read intact and in order: the rest may be late, not lost
    shortfall: bool = False


def judge_answers(out: Backlog, action: int | Sequence[int], requests: int) -> Verdict | None:
    """The first thing wrong with the answers read: cut short or malformed (F5), not the expected answer
    (A1), fewer than the requests (S6, A1: lost, with where the first one was lost when the requests' actions
    tell it), or more (A1). ``action``: every request's, or each request's in order. None: every answer intact,
    in order, one each."""
    actions = [action] * requests if isinstance(action, int) else action
    if len(out.received) == requests * ANSWER_LEN and bytes(out.received) == _expected(actions[:requests]):
        return None  # every answer as it should be (the common case, judged at once)
    decoder = StreamDecoder(expect=TransferType.BOX_TO_ROBOT)
    events = decoder.feed(bytes(out.received))
    offset, good = 0, 0
    got: list[int] = []
    for event in events:
        if isinstance(event, ProtocolError):
            at = event.offset or offset
            return Verdict("F5", f"answer {good + 1} a whole frame (12 + N×L + 2 bytes)",
                           f"after {good} intact answer(s), at byte {at} of {len(out.received)} read: {event}"
                           f"{first_lost(actions, got)}", _around(out.received, at))
        assert isinstance(event, Frame)
        want = actions[good] if good < len(actions) else None
        if int(event.action) != want or event.error_code != 0:
            later = [int(e.action) for e in events[good : good + ALIGN] if isinstance(e, Frame)]
            lost = first_lost(actions, later, good, max(0, requests - len(events)))
            if event.error_code == 0 and lost:
                return Verdict("S6", f"{requests} answers, one per request, in order, however late the robot reads",
                               f"answer {good + 1} at byte {offset} is a later request's: {event.describe()}{lost}",
                               _around(out.received, offset))
            return Verdict("A1", f"answer {good + 1} echoes action {want if want is None else f'{want:02X}'} with "
                           "error 0000 (in request order)", f"answer {good + 1} at byte {offset}: {event.describe()}",
                           _around(out.received, offset))
        got.append(int(event.action))
        offset += HEADER_LEN + len(event.blocks) * event.block_length + CHECK_LEN
        good += 1
    tail = decoder.buffered
    if good < requests and out.ended == "budget":
        return None  # answers still coming, all intact so far: too slow to wait for, not lost (the case says so)
    if good < requests:
        why = {"closed": "then the box closed the connection", "reset": "then the box reset the connection",
               "silent": "then nothing more came for time_out", "blocked": "the box stopped reading"}.get(out.ended, "")
        cut = f"; the last {tail} byte(s) are a frame cut short (F5)" if tail else ""
        return Verdict("S6", f"{requests} answers, one per request, however late the robot reads them",
                       f"{good} intact answers ({len(out.received)} bytes of the {requests * ANSWER_LEN} due): "
                       f"{requests - good} lost{cut}" + (f"; {why}" if why else "") + first_lost(actions, got),
                       _around(out.received, max(0, offset - 14)), shortfall=not tail)
    if good > requests:
        return Verdict("A1", f"{requests} answers, one per request", f"{good} answers", b"")
    return None


#: how many answers after the first wrong one :func:`first_lost` lines up with a later run of the requests
ALIGN = 24


def _expected(actions: Sequence[int]) -> bytes:
    """The blockless 0000 answers to ``actions``, in order (what a run of them must read)."""
    known = {a: encode(answer(Action(a))) for a in set(actions) if a in _BLOCKLESS}
    return b"".join(known[a] for a in actions) if len(known) == len(set(actions)) else b""


def first_lost(actions: Sequence[int], answers: Sequence[int], at: int | None = None, most: int = 0) -> str:
    """Where the first answer was lost, from the requests' actions: ``answers`` (the actions of up to ALIGN answers
    from ``at`` on) are those of the requests ``k`` later (the smallest such ``k`` up to ``most``), so the first
    lost answer lies between the last request whose action the shift leaves unchanged and ``at``. ``at`` None:
    ``answers`` are every intact answer, and the first lost one is after them. "" when nothing tells it."""
    if at is None:  # every answer so far matched its request: with mixed actions, the loss began after them
        if len(set(actions)) < 2:
            return ""  # one action throughout: which answers were lost cannot be told
        return f"; the first lost answer is request {len(answers) + 1}'s (answers 1 to {len(answers)} match)"
    want = list(answers)
    for k in range(1, most + 1):
        if want and want == list(actions[at + k : at + k + len(want)]):
            first = at
            while first > 0 and actions[first - 1] == actions[first - 1 + k]:
                first -= 1
            where = f"request {at + 1}'s" if first == at else f"that of one of requests {first + 1} to {at + 1}"
            return (f"; answers lost: answer {at + 1} and the {len(want) - 1} after it are those of requests {at + k + 1} "
                    f"on, so the first lost answer is {where} (answers 1 to {first} match)")
    return ""


def _around(data: bytearray, offset: int) -> bytes:
    return bytes(data[max(0, offset - 14) : offset + SHOWN])
