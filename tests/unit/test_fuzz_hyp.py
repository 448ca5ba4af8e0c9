"""The hypothesis adapter (conformance/fuzz/hyp.py), checked against the installed hypothesis.

If one of these fails after a hypothesis upgrade, the private attributes the adapter
sets no longer do what it says: fix the adapter (and widen ``CHECKED``), not the campaign.
"""

from __future__ import annotations

import hypothesis
from hypothesis import Phase, given, settings
from hypothesis import strategies as st
from hypothesis.database import InMemoryExampleDatabase
from hypothesis.stateful import RuleBasedStateMachine, rule, run_state_machine_as_test

from conformance.fuzz import hyp


def test_the_installed_hypothesis_is_one_the_adapter_was_checked_against() -> None:
    assert hyp.supported(), f"hypothesis {hypothesis.__version__} is outside {hyp.CHECKED}: recheck conformance/fuzz/hyp.py"


def _drawn(seed: int) -> list[int]:
    seen: list[int] = []

    @settings(max_examples=20, database=None, phases=[Phase.generate])
    @given(st.integers())
    def test(x: int) -> None:
        seen.append(x)

    hyp.seed_test(test, seed)
    test()
    return seen


def test_seed_test_repeats_the_examples_and_another_seed_changes_them() -> None:
    assert _drawn(7) == _drawn(7)
    assert _drawn(7) != _drawn(8)


def _saved_keys(digest: bytes) -> set[bytes]:
    db = InMemoryExampleDatabase()

    @settings(max_examples=50, database=db, phases=[Phase.generate, Phase.shrink])
    @given(st.integers())
    def test(x: int) -> None:
        assert x < 10

    hyp.set_database_key(test, digest)
    hyp.seed_test(test, 1)
    try:
        test()
    except AssertionError:
        pass
    return set(db.data)


def test_the_database_key_follows_the_digest() -> None:
    a, b = _saved_keys(b"campaign-a"), _saved_keys(b"campaign-b")
    assert a and b and not a & b  # different digests: the failure is saved under different keys
    assert _saved_keys(b"campaign-a") == a  # the same digest: the same key (a later campaign replays it)


def test_seed_machine_repeats_a_state_machine_run() -> None:
    runs: list[list[int]] = []

    class Machine(RuleBasedStateMachine):
        @rule(x=st.integers(0, 10**6))
        def step(self, x: int) -> None:
            runs[-1].append(x)

    def once(seed: int) -> list[int]:
        runs.append([])
        hyp.seed_machine(Machine, seed)
        run_state_machine_as_test(Machine, settings=settings(max_examples=3, stateful_step_count=5, database=None,
                                                              phases=[Phase.generate]))
        return runs[-1]

    assert once(3) == once(3) and once(3) != once(4)
