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

import pytest

from conformance.harness.client import Closed
from conformance.protocol import (
    Action,
    encode,
    request,
)
from conformance.suite import NOT_OK, CaseContext, Level, Requirement, answered_zero, case
from conformance.suite.boundary_requests import (
    ACTION_IDS,
    ACTIONS,
    COUNTS,
    Judged,
    answered_ok,
    blocks,
    exchange_all,
    float_requests,
    named_error,
    wrong_index,
    wrong_positions,
)


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
             for label, blks, where, bits in float_requests(action, isight.profile.first_index)]
    exchange_all(isight, items).finish()
