"""Lanes: which cases of one box may run side by side, and how ``run`` deals them out.

A slow box (every answer 100 ms late, say) costs the suite its latency once per exchange,
and a run makes about a thousand. S4 asks a box to serve several connections at once, so
cases that only send requests and judge the answers, each on its own connections, can run
in parallel lanes (pytest-xdist workers) when the box is slow and does serve two connections
at once (:func:`conformance.harness.concurrency.probe_lanes` decides; ``run --lanes``).

A case shares the box (``@case(..., shares_box=True)``) when it sets no box-wide state (no
CycleOn/CycleOff: S3 leaves it to the box whether the cycle is per box or per connection;
no extension E state), judges no timing, and holds no crowd of connections. Everything else
runs *alone*, one case after the other, once every lane is done
(:class:`conformance.xdist_hooks.LaneScheduling`). A parametrised case whose parameter
makes it stateful (a golden vector that carries a CycleOn) is marked :data:`ALONE_MARK`.
"""

from __future__ import annotations

from collections.abc import Iterable

import pytest

from ..suite.record import ALONE_MARK, STATELESS, info_of, stateless_frame  # noqa: F401 - the lanes' API too

#: the scope of the cases that run alone, after the lanes
ALONE = "isight-alone"
#: a parameter's mark: this variant of a shared case runs alone
#: lanes ``run --lanes auto`` uses for a slow box that serves several connections
AUTO_LANES = 3
#: a run in lanes: each case's scope (node id -> a lane or :data:`ALONE`), on the controller's config
LANE_PLAN = pytest.StashKey[dict[str, str]]()


def lanes_of(plan: dict[str, str] | None) -> int:
    """How many lanes a plan deals cases into (1: none, one case at a time)."""
    return max(1, len({scope for scope in (plan or {}).values() if scope != ALONE}))


def lane_name(i: int) -> str:
    return f"isight-lane-{i}"


def shares_box(item: pytest.Item) -> bool:
    info = info_of(item)
    return info is not None and info.shares_box and item.get_closest_marker(ALONE_MARK) is None



def plan(items: Iterable[pytest.Item], lanes: int) -> dict[str, str]:
    """Each case's scope: the shared ones dealt round-robin over ``lanes`` lanes in catalogue
    order (each lane gets a mix of families), the rest :data:`ALONE`."""
    scopes: dict[str, str] = {}
    dealt = 0
    for item in items:
        if lanes > 1 and shares_box(item):
            scopes[item.nodeid] = lane_name(dealt % lanes)
            dealt += 1
        else:
            scopes[item.nodeid] = ALONE
    return scopes
