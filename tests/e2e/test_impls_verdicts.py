"""The suite against implementations that are not ours (tests/impls), end to end.

Each test starts one independent box (``python -m tests.impls.box NAME``) or robot and runs
the real command line against it (``isight-conformance run`` / ``certify-robot``) exactly as
``python -m tests.impls.matrix`` does, then judges the run by ``tests/impls/expectations.py``:

- a conforming implementation (each makes the legal choices differently) comes out clean:
  exit 0, no FAIL, ERROR or NON-STRICT;
- a broken one (one planted defect each) is caught, and the first root cause in
  ``summary.json`` names the planted clause at the right level; each sits on a random legal
  base (:data:`BASE_SEED` and its name draw the knobs), not on the reference box's choices;
- a few random legal combinations of the box's knobs, and of the robot's, come out clean
  (``python -m tests.impls.matrix --sample`` runs more).

The conforming boxes also run the fuzz cases under a second seed. Broken boxes run with a
2 s time_out (they are caught either way; their silences cost less), conforming ones with
the default. Every process has a hard wall-clock bound and a memory cap (the matrix's).
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import pytest

from tests.impls.expectations import EXPECTATIONS, RANDOM, Expectation, expectation
from tests.impls.matrix import Row, run_box, run_robot, sample_seeds

pytestmark = pytest.mark.impls

BOXES = [e for e in EXPECTATIONS.values() if e.role == "box"]
ROBOTS = [e for e in EXPECTATIONS.values() if e.role == "robot"]
SECOND_SEED = 7  # the fuzz cases' default seed is the first
BASE_SEED = 17  # the broken boxes' random legal bases (the matrix's --base-seed)
#: the random legal combinations CI runs (the matrix's --sample N --seed SAMPLE_SEED runs the same first N)
SAMPLE_SEED, BOX_SAMPLES, ROBOT_SAMPLES = 1, 3, 3
#: about how long each run takes on a 2-core machine (s): tests/conftest.py starts the longest first. A box that
#: stays silent after garbage, or drops coalesced requests, costs a time_out in each of ~60 malformed-input cases
SECONDS = {"no-resync": 200, "drops-coalesced": 160, "one-at-a-time": 55, "byte-by-byte": 37, "drops-frames": 100,
           "sticky-error": 90, "answers-some-actions": 70, "short-send-drops": 60, "late-inside-timeout": 120,
           "drops-rest-of-read": 150, "split-header-lost": 90, "slow-cycle-on": 120, "slow-pieces": 60}


def params(exps: list[Expectation], default: float, known: dict[str, float] | None = None) -> list[object]:
    known = SECONDS if known is None else known
    return [pytest.param(e, id=e.name, marks=pytest.mark.impls(seconds=known.get(e.name, default))) for e in exps]


def run(exp: Expectation, tmp_path: Path, *, time_out: int = 0, seed: int = 0, limit: float = 240,
        base_seed: int = 0) -> Row:
    args = argparse.Namespace(time_out=time_out, limit=limit, mem_limit=1024, base_seed=base_seed)
    runner = run_box if exp.role == "box" else run_robot
    return runner(exp, args, tmp_path, seed, bool(seed))


def explain(row: Row) -> str:
    causes = "; ".join(row.root_causes or []) or "none"
    return (f"{row.name}: {row.judgement} (exit {row.exit}, {row.wall_s} s, {row.peak_rss_mb} MB, totals {row.totals}); "
            f"first: {' | '.join(row.first) or '-'}; root causes: {causes}; notes: {'; '.join(row.notes) or '-'}")


@pytest.mark.parametrize("exp", params([e for e in BOXES if e.conforming], 25))
def test_a_conforming_box_comes_out_clean(exp: Expectation, tmp_path: Path) -> None:
    row = run(exp, tmp_path)
    assert row.judgement == "ok", explain(row)
    assert row.exit == 0 and not row.notes, explain(row)


@pytest.mark.parametrize("exp", params([e for e in BOXES if e.conforming], 5, {}))
def test_a_conforming_box_survives_the_fuzz_cases_under_another_seed(exp: Expectation, tmp_path: Path) -> None:
    fuzz_only = dataclasses.replace(exp, suite_args=(*exp.suite_args, "--cases", "FUZZ-*"))
    row = run(fuzz_only, tmp_path, seed=SECOND_SEED)
    assert row.judgement == "ok", explain(row)
    assert row.totals.get("PASS", 0) >= 1, explain(row)  # the fuzz cases did run


@pytest.mark.parametrize("exp", params([e for e in BOXES if not e.conforming], 20))
def test_a_broken_box_is_blamed_on_its_defect(exp: Expectation, tmp_path: Path) -> None:
    row = run(exp, tmp_path, time_out=2000, base_seed=BASE_SEED, limit=420)  # no-resync: 249 s under load
    assert row.judgement == "ok", explain(row)
    assert row.root_causes, explain(row)  # the first root cause named the defect (not a weaker first-case check)


#: T2's jitter is the scheduling of a Python robot on a loaded CI machine as much as the robot's: none of
#: the robots here has a jitter defect (slow-stream's is its rate, T2-01), so jitter is judged loosely
LOOSE_JITTER = ("--jitter-tolerance", "400")


@pytest.mark.parametrize("exp", params(ROBOTS, 4))
def test_a_robot_is_judged_by_certify_robot(exp: Expectation, tmp_path: Path) -> None:
    row = run(dataclasses.replace(exp, suite_args=(*exp.suite_args, *LOOSE_JITTER)), tmp_path)
    # a robot's defect fails one case: without a shared root cause the first failing case must name it ("ok?")
    assert row.judgement in (("ok",) if exp.conforming else ("ok", "ok?")), explain(row)


@pytest.mark.parametrize("seed", [pytest.param(s, id=f"box-{s}", marks=pytest.mark.impls(seconds=90))
                                  for s in sample_seeds(SAMPLE_SEED, BOX_SAMPLES)])
def test_a_random_legal_box_comes_out_clean(seed: int, tmp_path: Path) -> None:
    """The full suite, fuzz cases under the combination's seed, against a random legal combination of the knobs."""
    row = run(expectation(RANDOM), tmp_path, seed=seed)
    assert row.judgement == "ok", explain(row) + f"; knobs: {row.knobs}"


@pytest.mark.parametrize("seed", [pytest.param(s, id=f"robot-{s}", marks=pytest.mark.impls(seconds=8))
                                  for s in sample_seeds(SAMPLE_SEED, ROBOT_SAMPLES)])
def test_a_random_legal_robot_is_certified_clean(seed: int, tmp_path: Path) -> None:
    row = run(expectation(RANDOM, "robot"), tmp_path, seed=seed)
    assert row.judgement == "ok", explain(row) + f"; knobs: {row.knobs}"
