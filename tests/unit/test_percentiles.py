"""conformance.model.percentiles: the one percentile definition every figure uses."""

from __future__ import annotations

import math
import statistics

from hypothesis import given
from hypothesis import strategies as st

from conformance.model.percentiles import percentile


def test_small_cases() -> None:
    assert math.isnan(percentile([], 50))
    assert percentile([7.0], 99) == 7.0
    assert percentile([5.0, 1.0, 3.0], 50) == 3.0  # unsorted input is fine
    assert percentile([0.0, 10.0], 25) == 2.5
    assert percentile(iter([1.0, 2.0, 3.0]), 100) == 3.0


@given(st.lists(st.floats(-1e6, 1e6), min_size=2, max_size=200))
def test_agrees_with_statistics(values: list[float]) -> None:
    assert math.isclose(percentile(values, 50), statistics.median(values), rel_tol=1e-9, abs_tol=1e-6)
    q = statistics.quantiles(values, n=100, method="inclusive")
    assert math.isclose(percentile(values, 99), q[98], rel_tol=1e-9, abs_tol=1e-6)
