"""The pytest plugin takes resolved settings handed over as an object (``isight-conformance run``'s way)
and, with no object, resolves its flags (``pytest --pyargs conformance.cases ...``): the same selection
either way. Collection only: no box is started."""

from __future__ import annotations

import pytest

from conformance.runtime.settings import SettingsPlugin, SuiteSettings

pytest_plugins = ["pytester"]

CASES = """
from conformance.suite.record import case

@case("A4-01", ["A4"], "MUST", "one", "e")
def test_one(isight):
    pass

@case("A4-02", ["A4"], "MUST", "two", "e")
def test_two(isight):
    pass
"""


def _collected(pytester: pytest.Pytester, *args: str, plugins: list[object] | None = None) -> list[str]:
    path = pytester.makepyfile(test_cases=CASES)
    recorder = pytester.inline_run(path, "-p", "no:cacheprovider", "--collect-only", *args, plugins=plugins or [])
    return [item.name for item in recorder.getcalls("pytest_collection_finish")[0].session.items]


def test_settings_handed_as_an_object_select_the_cases(pytester: pytest.Pytester) -> None:
    handed = SettingsPlugin(SuiteSettings(cases=("A4-02",)))
    assert _collected(pytester, plugins=[handed]) == ["test_two"]


def test_without_an_object_the_flags_are_resolved(pytester: pytest.Pytester) -> None:
    assert _collected(pytester, "--cases", "A4-02") == ["test_two"]
    assert _collected(pytester) == ["test_one", "test_two"]
