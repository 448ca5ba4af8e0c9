"""Boundaries (B1-B4): block counts at every place an index counter may wrap, a wrong index
at the 17th, 129th and last block, and the float values a hurried implementation gets wrong.

* B3-03: 1, 2, 15, 16, 17, 31, 32, 100, 127, 128, 129, 254 and 255 blocks, each request
  well-formed: answered 0000 (A1, A3). A box whose index counter wraps at 16 (4 bits) or
  128 refuses the requests from 17 or 129 blocks on.
* B3-04: one wrong index at the 17th, the 129th and the last block of those requests:
  a parse error (never 0000, R1; SHOULD 1001/1002, A3). At the 17th and 129th block the
  wrong index is the one a counter wrapping at 16 or 128 would expect there (the first
  index again); at the last block, a gap.
* B4-03: 0.0, -0.0, subnormals, the largest finite float32 of either sign, +-1e6, and a
  negative value in every coordinate and in a tolerance: legal values (B1, B2, B4), so
  the request is answered 0000; a refusal breaks A3/A1.

Cycle state: pose (23), register pose (24) and tolerance (25) requests are answered 0000
in every cycle state (``answers.ALLOWED_CODES``, S3), so no case here sets one up.

Each case sends its requests on one connection, one after the other (a fresh connection
only when the box closed one), and judges every one: its verdict is the worst one (the
first request that earned it), and its details list every request that got another
outcome, so acceptance that changes at a block position shows whole. A box that stops
answering ends the case there (bounded time: one time_out, not one per request).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import pytest

from conformance.protocol import (
    ACTION_ERROR,
    Action,
    Block,
    PoseBlock,
    ToleranceBlock,
    encode,
    request,
)
from conformance.protocol.constants import EDGE_FLOAT32, f32_bits, f32_of_bits
from conformance.suite import (
    NOT_OK,
    Answer,
    CaseContext,
    CaseVerdict,
    Closed,
    Expect,
    Level,
    Outcome,
    Requirement,
    Silence,
    Skip,
    Verdict,
    answered,
    answered_allowed,
    answered_zero,
    case,
)

# -- the family's helpers: Helpers of the B3-03/B3-04/B4-03 boundary cases (conformance/cases/boundaries.py): block counts, wrong indexes, legal float values, judged in one batch.
POSE, REG, TOL = Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE

ACTIONS = [POSE, REG, TOL]

ACTION_IDS = ["pose", "register-pose", "tolerance"]

#: block counts around every place an index counter may wrap (4, 7 and 8 bits), and the ends
COUNTS = (1, 2, 15, 16, 17, 31, 32, 100, 127, 128, 129, 254, 255)

#: block positions (1-based) where a wrong index is planted, besides the last one
WRAP_POSITIONS = (17, 129)

#: (id, float32 bit pattern): every float of the block holds it
FLOAT_VALUES = [
    ("zero", 0x00000000),
    *EDGE_FLOAT32,
    ("1e6", 0x49742400),
    ("neg-1e6", 0xC9742400),
]

BASE_POSE = (640.0, 12.5, 280.0, 180.0, 10.0, 90.0)

COORDINATES = ("x", "y", "z", "w", "p", "r")

#: the verdicts a request can earn here, worst first
WORST_FIRST = (Verdict.FAIL, Verdict.ERROR, Verdict.NON_STRICT, Verdict.INCONCLUSIVE)


def value_of(bits: int) -> float:
    """The float32 with this bit pattern (as a Python float: encoding it again gives the same bits)."""
    return f32_of_bits(bits)


def sample_block(action: Action, index: int, k: int) -> Block:
    if action is TOL:
        return ToleranceBlock(index, 0.25 + 0.5 * k)
    return PoseBlock(index, (500.0 + k, -20.5 * k, 300.25, 180.0, -0.5 * k, 90.0))


def blocks(action: Action, count: int, first: int, wrong_at: int = 0) -> tuple[Block, ...]:
    """``count`` blocks indexed from ``first``; block ``wrong_at`` (1-based, 0: none) with :func:`wrong_index`."""
    out = []
    for k in range(count):
        index = wrong_index(k + 1, first) if k + 1 == wrong_at else (first + k) & 0xFF
        out.append(sample_block(action, index, k))
    return tuple(out)


def wrong_index(position: int, first: int) -> int:
    """The wrong index planted at ``position``: at 17 and 129 what a counter wrapping at 16 or 128
    expects there (the first index again); at the last position of a request, a gap (+1)."""
    if position in WRAP_POSITIONS:
        return first
    return (first + position) & 0xFF


def wrong_positions(count: int) -> list[int]:
    """Where a request of ``count`` blocks gets its wrong index: the 17th, 129th and last block
    (a one-block request has no index after the first: B3-02's wrong start covers it)."""
    return sorted({p for p in (*WRAP_POSITIONS, count) if 2 <= p <= count})


def answered_ok(action: int, **_: object) -> Expect:
    return answered_allowed(action)


def named_error(action: int, **_: object) -> Expect | None:
    error = ACTION_ERROR.get(Action(action))
    return None if error is None else answered(action, [error])


class Judged:
    """Judges every request of a case on one connection (a fresh one after a close), keeps the
    first verdict of each kind, and raises the worst at :meth:`finish`."""

    def __init__(self, isight: CaseContext, label: str = "command") -> None:
        self.isight = isight
        self.label = label
        self.first: dict[Verdict, CaseVerdict] = {}
        #: the labels of the requests that did not pass
        self.broken: list[str] = []
        self.judged = 0
        self.stopped = ""
        self.conn = isight.connect(label)

    def judge(self, label: str, outcome: Outcome, sent: bytes, **values: Any) -> bool:
        """True when ``outcome`` passes; else the verdict is kept for :meth:`finish`."""
        self.judged += 1
        try:
            self.isight.judge(outcome, sent=sent, **values)
        except Skip:
            raise
        except CaseVerdict as verdict:
            verdict.message = f"{label}: {verdict.message}"
            verdict.args = (verdict.message,)
            self.first.setdefault(verdict.verdict, verdict)
            self.broken.append(label)
            return False
        return True

    def go_on(self, outcome: Outcome | None, left: int) -> bool:
        """After a request: False (and why) when the box went silent or cannot be reached again;
        a fresh connection when it closed this one."""
        if isinstance(outcome, Silence):
            self.stopped = f"the box went silent; the {left} requests after it were not sent"
            return False
        if left and (isinstance(outcome, Closed) or self.conn.closed_by_peer is not None):
            self.conn.close()
            try:
                self.conn = self.isight.connect(self.label)
            except CaseVerdict as exc:  # unreachable now: what was judged stands
                self.stopped = f"the box could not be reached again ({exc.message}); {left} requests were not sent"
                return False
        return True

    def finish(self) -> None:
        """Raise the worst verdict kept (PASS when none), naming every other request that did not pass."""
        self.conn.close()
        self.isight.details["judged"] = self.judged
        for key, found in (("not_passed", self.broken), ("stopped", self.stopped)):
            if found:
                self.isight.details[key] = found
        worst = next((self.first[v] for v in WORST_FIRST if v in self.first), None)
        if worst is None:
            if self.stopped:
                self.isight.inform(self.stopped)
            return
        others = [b for b in self.broken if not worst.message.startswith(f"{b}:")]
        if others:
            worst.message += f" (also not passed: {', '.join(others[:12])}{' …' if len(others) > 12 else ''})"
        if self.stopped:
            worst.message += f"; {self.stopped}"
        worst.args = (worst.message,)
        raise worst


def exchange_all(isight: CaseContext, items: Sequence[tuple[str, bytes, Mapping[str, object]]]) -> Judged:
    """Send each well-formed request on one connection, one after the other, and judge each answer."""
    judged = Judged(isight)
    for n, (label, raw, values) in enumerate(items):
        outcome = judged.conn.request(raw, label)
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)
        judged.judge(label, outcome, raw, **values)
        if not judged.go_on(outcome, len(items) - n - 1):
            break
    return judged


def float_requests(action: Action, first: int) -> list[tuple[str, tuple[Block, ...], str, int]]:
    """(label, blocks, where, bits): every float of the block at each value, then one negative coordinate."""
    out: list[tuple[str, tuple[Block, ...], str, int]] = []
    for name, bits in FLOAT_VALUES:
        value = value_of(bits)
        block: Block = ToleranceBlock(first, value) if action is TOL else PoseBlock(first, (value,) * 6)
        out.append((name, (block,), "every float", bits))
    if action is TOL:
        out.append(("negative-tolerance", (ToleranceBlock(first, -0.5),), "the tolerance", 0xBF000000))
        return out
    for i, axis in enumerate(COORDINATES):
        x, y, z, w, p, r = (-v if k == i else v for k, v in enumerate(BASE_POSE))
        bits = f32_bits(-BASE_POSE[i])
        out.append((f"negative-{axis}", (PoseBlock(first, (x, y, z, w, p, r)),), f"coordinate {axis}", bits))
    return out


# -- the cases

@case("B3-03", ["B3", "B1", "B2", "A1", "A3"], Level.MUST,
      "Requests with 1 to 255 blocks, around every place an index counter may wrap, are answered 0000",
      "1, 2, 15, 16, 17, 31, 32, 100, 127, 128, 129, 254 and 255 blocks, each answered with the request's action "
      "and 0000 (in any cycle state, S3); one connection, one request after the other",
      checks={"": Requirement(("A1", "A3"), "a well-formed {action.name} request with {count} blocks (indexes "
                              "{first} to {last}) is answered 0000", accept=answered_ok)}, shares_box=True)
@pytest.mark.parametrize("action", ACTIONS, ids=ACTION_IDS)
def test_block_count_boundaries(isight: CaseContext, action: Action) -> None:
    first = isight.profile.first_index
    items = [(f"{count} blocks", encode(request(action, blocks(action, count, first)), isight.profile),
              {"count": count, "first": first, "last": (first + count - 1) & 0xFF}) for count in COUNTS]
    judged = exchange_all(isight, items)
    # for root causes: valid requests refused from some block count on (an index counter that wraps)
    isight.details["refused_counts"] = [c for c in COUNTS if f"{c} blocks" in judged.broken]
    judged.finish()


@case("B3-04", ["B3", "A3", "R1"], Level.MUST,
      "A wrong index at the 17th, the 129th or the last block is a parse error",
      "not 0000 (MUST); answered 1001 for 23/24, 1002 for 25 (SHOULD, A3). At the 17th and 129th block the wrong "
      "index is the first index again (what a counter wrapping at 16 or 128 expects), at the last block a gap; "
      "requests of 2 to 255 blocks, on one connection",
      checks={"": Requirement(("B3", "R1"), "a {action.name} request whose block {position} of {count} has index "
                              "{index:02x} (expected {expected:02x}) is a parse error and MUST NOT be answered 0000",
                              accept=NOT_OK, should=named_error, should_clauses=("A3",),
                              should_text="a parse error in a {action.name} request SHOULD be answered with the "
                                          "action's error")}, shares_box=True)
@pytest.mark.parametrize("action", ACTIONS, ids=ACTION_IDS)
def test_wrong_index_positions(isight: CaseContext, action: Action) -> None:
    first = isight.profile.first_index
    judged = Judged(isight, "malformed")
    plan = [(count, position) for count in COUNTS for position in wrong_positions(count)]
    accepted: list[dict[str, int]] = []
    for n, (count, position) in enumerate(plan):
        bad = encode(request(action, blocks(action, count, first, position)), isight.profile)
        index, expected = wrong_index(position, first), (first + position - 1) & 0xFF
        outcome = isight.send_malformed(bad, f"{action.name}, {count} blocks, index {index:02x} at block {position}",
                                        conn=judged.conn)
        if answered_zero(outcome):
            accepted.append({"count": count, "position": position, "index": index})
        judged.judge(f"block {position} of {count}", outcome, bad, count=count, position=position, index=index,
                     expected=expected)
        # the probe tells whether the box is still there: a close ends the connection, silence the case
        after = outcome if isinstance(outcome, Closed) else isight.last_probe
        if not judged.go_on(after, len(plan) - n - 1):
            break
    # for root causes: where a wrong index was answered 0000 (an index counter that wraps)
    isight.details["accepted_wrong_index"] = accepted
    judged.finish()


@case("B4-03", ["B4", "B1", "B2", "A1", "A3"], Level.MUST,
      "Any finite float32 is a legal value: zero, -0.0, subnormals, the largest, 1e6, negatives",
      "answered with the request's action and 0000 (in any cycle state, S3): 0.0, -0.0, subnormals, the largest "
      "finite float32 of either sign, 1e6 and -1e6 in every float, a negative value in each coordinate and in a "
      "tolerance; one connection, one request after the other",
      checks={"": Requirement(("A1", "A3", "B4"), "float32 {bits:08X} ({name}) in {where} is a legal value; the "
                              "well-formed {action.name} request is answered 0000", accept=answered_ok)},
      shares_box=True)
@pytest.mark.parametrize("action", ACTIONS, ids=ACTION_IDS)
def test_legal_float_values(isight: CaseContext, action: Action) -> None:
    items = [(label, encode(request(action, blks), isight.profile), {"name": label, "where": where, "bits": bits})
             for label, blks, where, bits in float_requests(action, isight.codec.block_index(0))]
    exchange_all(isight, items).finish()
