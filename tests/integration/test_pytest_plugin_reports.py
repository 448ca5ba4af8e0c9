"""The plugin shapes a case's report from its verdict through public hooks only: a case that
raises gets a one-line ``longrepr`` (no traceback parsed from sources), and its items are not
patched. Runs two cases against the bundled reference box in-process (about 2 s)."""

from __future__ import annotations

import pytest

pytest_plugins = ["pytester"]

CASES = """
from conformance.suite.record import case

@case("A4-01", ["A4"], "MUST", "raises", "e")
def test_raises(isight):
    raise RuntimeError("the suite's own bug")

@case("A4-02", ["A4"], "MUST", "passes", "e")
def test_passes(isight):
    pass
"""


def test_a_raising_case_gets_one_line_and_no_traceback(pytester: pytest.Pytester) -> None:
    path = pytester.makepyfile(test_cases=CASES)
    recorder = pytester.inline_run(path, "-p", "no:cacheprovider", "--capture", "no")
    reports = {r.nodeid.rpartition("::")[2]: r for r in recorder.getreports("pytest_runtest_logreport")
               if r.when == "call"}
    raised, passed = reports["test_raises"], reports["test_passes"]
    assert raised.failed and passed.passed
    assert ("isight_verdict", "ERROR") in raised.user_properties
    assert "RuntimeError: the suite's own bug" in raised.longreprtext
    assert "def test_raises" not in raised.longreprtext and "Traceback" not in raised.longreprtext
    items = pytester.inline_genitems(path, "-p", "no:cacheprovider")[0]
    assert all("repr_failure" not in vars(item) and "_repr_failure_py" not in vars(item) for item in items)
