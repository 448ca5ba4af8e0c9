"""Every judge over the legal space, sampled (issue 26): robot ↔ ``monitor`` ↔ box pairs, ``analyze`` on the
monitor's capture, ``certify-robot`` on the robot; all must agree.

CI samples a few pairs (``ISIGHT_PAIRS_SEED`` picks others; the full sweep is
``python -m tests.impls.pairs --robots 10 --boxes 5 --broken``, see docs/MONITOR.md): two random
legal robots against one random legal box, a broken robot on a random legal base, and a
broken box on a random legal base. Each pair runs in its own processes with bounded waits.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import pytest

from tests.impls.matrix import sample_seeds
from tests.impls.pairs import PARTNER_BOX, RANDOM, Side, certify, run_pair

pytestmark = pytest.mark.impls(seconds=20)

SEED = int(os.environ.get("ISIGHT_PAIRS_SEED", "26"))
ROBOTS = sample_seeds(SEED, 2)
BOX = sample_seeds(SEED + 7919, 1)[0]
BASE = sample_seeds(SEED + 104729, 2)
ARGS = argparse.Namespace(duration=1.0)

PAIRS = [
    # issue 26's report: a pose (23) and a register pose (24) on the command connection, legal, read as ROBOT A1
    pytest.param(Side("karel-calls", 0), Side(PARTNER_BOX, 0), id="karel-calls-resync-fine"),
    pytest.param(Side(RANDOM, ROBOTS[0]), Side(RANDOM, BOX), id=f"legal-robot{ROBOTS[0]}-box{BOX}"),
    pytest.param(Side(RANDOM, ROBOTS[1]), Side(RANDOM, BOX), id=f"legal-robot{ROBOTS[1]}-box{BOX}"),
    pytest.param(Side("little-floats", BASE[0]), Side(PARTNER_BOX, 0), id=f"broken-robot-F4-base{BASE[0]}"),
    pytest.param(Side(RANDOM, ROBOTS[0]), Side("wrong-transfer-type", BASE[1]), id=f"broken-box-F3-base{BASE[1]}"),
]


@pytest.mark.parametrize(("robot", "box"), PAIRS)
def test_monitor_and_analyze_agree_on_the_pair(robot: Side, box: Side, tmp_path: Path) -> None:
    row = run_pair(robot, box, ARGS, tmp_path)
    assert row.judgement in ("ok",) or row.judgement.startswith("NOT EXERCISED"), (row.judgement, row.verdicts,
                                                                                   row.notes)
    assert row.verdicts["monitor"] == row.verdicts["analyze"]  # the same capture, the same engine
    if not robot.broken and not box.broken:
        assert row.verdicts["monitor"] == "clean"


@pytest.mark.parametrize("robot", [Side(RANDOM, ROBOTS[0]), Side("karel-calls", 0), Side("little-floats", BASE[0])],
                         ids=["legal", "karel-calls", "broken-F4"])
def test_certify_robot_agrees_on_the_sampled_robot(robot: Side, tmp_path: Path) -> None:
    verdict, cases = certify(robot, ARGS, tmp_path)
    assert verdict.startswith("ok"), (verdict, cases)
