"""Shared test configuration: hypothesis profiles, the tier markers, and the slow end-to-end runs first.

The tests sit in three tiers, one directory each, and each test is marked with its tier:
``tests/unit`` (``unit``: pure, no sockets, threads or processes; the fast loop, ``pytest tests/unit``),
``tests/integration`` (``integration``: sockets and threads on loopback) and ``tests/e2e`` (``e2e``:
processes, Chromium, tshark, the runs against tests/impls). ``-m unit`` or ``-m 'not e2e'`` select by tier.

``dev`` (default) keeps hypothesis's example database in .hypothesis/; ``ci`` (set
HYPOTHESIS_PROFILE=ci, as .ci/run does) runs derandomised with no deadline so a CI
run is reproducible on a loaded 2-core machine.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile("dev", deadline=None)
settings.register_profile(
    "ci", deadline=None, derandomize=True, print_blob=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))


TIERS = ("unit", "integration", "e2e")
_HERE = Path(__file__).resolve().parent


def tier_of(path: Path) -> str | None:
    """The tier of a test module: the tier directory it sits in under tests/ (None outside them)."""
    try:
        first = path.resolve().relative_to(_HERE).parts[0]
    except (ValueError, IndexError):
        return None
    return first if first in TIERS else None


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Each test marked with its tier (its directory); then the end-to-end runs against tests/impls first,
    the longest first (their ``impls(seconds=...)`` hint).

    Under pytest-xdist with small scheduling chunks (the README's ``-n 8 --maxschedchunk 2``) every worker
    then starts on one of them and the short tests fill in around them, instead of a worker being left with
    a two-minute run at the end. The sort is stable and the same on every worker, as xdist requires."""
    def weight(item: pytest.Item) -> float:
        mark = item.get_closest_marker("impls")
        return -float(mark.kwargs.get("seconds", 1)) if mark else 0.0

    for item in items:
        tier = tier_of(item.path)
        if tier is not None:
            item.add_marker(tier)
    items.sort(key=weight)


@pytest.fixture(autouse=True)
def _english_unless_a_test_chooses(monkeypatch: pytest.MonkeyPatch) -> None:
    """The commands take their language from the locale (--lang's default); the tests assert English
    output, so a Chinese locale on the test machine is overridden (tests/integration/test_i18n.py sets its own)."""
    from conformance.i18n import default_lang

    if default_lang() != "en":
        monkeypatch.setenv("LC_ALL", "C.UTF-8")
