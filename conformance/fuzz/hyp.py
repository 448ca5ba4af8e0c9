"""The one place that touches hypothesis's private attributes (an adapter, checked against the installed version).

A campaign runs hypothesis in chunks, each with a seed derived from the campaign's
and all under one database key. Hypothesis's public ``@seed`` also switches the
example database off, and there is no public way to name the database key of a
test; both are set through attributes hypothesis reads internally:

* ``_hypothesis_internal_use_seed`` on the test function (or on a state machine
  class): what ``@seed`` sets;
* ``_hypothesis_internal_add_digest`` on the inner test: bytes mixed into the test's
  database key (``@given`` tests built from the same function share a key).

``tests/unit/test_fuzz_hyp.py`` checks, for the installed hypothesis, that the attributes
still do what this module says (the same seed repeats the examples, the digest
changes the key) and that the version is one this adapter was checked against
(:data:`CHECKED`); a hypothesis upgrade that breaks them fails that test, not a campaign.
"""

from __future__ import annotations

from typing import Any

import hypothesis

#: hypothesis versions (from, up to but not including) this adapter was checked against.
CHECKED = ((6, 100), (7, 0))

_SEED = "_hypothesis_internal_use_seed"
_DIGEST = "_hypothesis_internal_add_digest"


def version() -> tuple[int, int]:
    major, minor = hypothesis.__version__.split(".")[:2]
    return int(major), int(minor)


def supported() -> bool:
    low, high = CHECKED
    return low <= version() < high


def seed_test(test: Any, seed: int) -> None:
    """What ``@seed(seed)`` does to a ``@given`` test, without switching its database off."""
    setattr(test, _SEED, seed)


def set_database_key(test: Any, digest: bytes) -> None:
    """Mix ``digest`` into the database key of a ``@given`` test (chunks of one campaign share it)."""
    setattr(test.hypothesis.inner_test, _DIGEST, digest)


def seed_machine(machine: type, seed: int) -> None:
    """Seed a ``RuleBasedStateMachine`` class for ``run_state_machine_as_test`` (the database stays on)."""
    setattr(machine, _SEED, seed)


__all__ = ["CHECKED", "seed_machine", "seed_test", "set_database_key", "supported", "version"]
