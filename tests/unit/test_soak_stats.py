"""The soak's statistics (issue 38): the sketch's quantiles, Theil–Sen with Sen's interval, Mann–Kendall."""

from __future__ import annotations

import math
import random

import pytest
from hypothesis import given
from hypothesis import strategies as st

from conformance.model.percentiles import percentile
from conformance.soak.sketch import GAMMA, LatencySketch
from conformance.soak.trend import mann_kendall, residual_spread, theil_sen, thin


@given(st.lists(st.floats(0.01, 60_000), min_size=1, max_size=400), st.sampled_from([0, 1, 50, 90, 99, 100]))
def test_sketch_quantile_is_within_its_bucket_of_a_sample_at_that_rank(values, q):
    sketch = LatencySketch(values)
    got = sketch.quantile(q)
    ordered = sorted(values)
    rank = q / 100 * (len(values) - 1)
    # the sketch returns a value within one bucket (2 %) of the sample at rank floor or ceil
    near = [ordered[math.floor(rank)], ordered[math.ceil(rank)]]
    assert any(abs(got - v) <= v * (GAMMA - 1) + 1e-9 for v in near), (got, near)
    assert sketch.count == len(values)
    assert sketch.max == max(values) and sketch.min == min(values)


def test_sketch_memory_is_bounded_by_the_range_not_the_count():
    rng = random.Random(1)
    sketch = LatencySketch(rng.lognormvariate(0, 1) for _ in range(200_000))
    assert sketch.count == 200_000
    assert len(sketch.buckets) < 1000
    assert math.isclose(sketch.quantile(50), 1.0, rel_tol=0.05)  # the lognormal's median is e^0


def test_sketch_empty_and_merge():
    empty = LatencySketch()
    assert math.isnan(empty.quantile(50)) and math.isnan(empty.mean)
    a, b = LatencySketch([1.0, 2.0]), LatencySketch([100.0])
    a.merge(b)
    assert a.count == 3 and a.max == 100.0 and a.quantile(100) == 100.0
    a.add(math.nan)  # an answer that never came is counted elsewhere, not here
    assert a.count == 3


def test_theil_sen_recovers_a_line_through_outliers():
    xs = [float(i) for i in range(30)]
    ys = [2.0 * x + 1.0 for x in xs]
    ys[3], ys[17], ys[25] = 500.0, -400.0, 1e6  # three wild windows
    fit = theil_sen(xs, ys)
    assert fit.slope == pytest.approx(2.0)
    assert fit.low <= 2.0 <= fit.high
    assert fit.intercept == pytest.approx(1.0, abs=0.5)


def test_theil_sen_of_a_perfect_line_has_a_zero_width_interval():
    fit = theil_sen([0.0, 1.0, 2.0, 3.0, 4.0], [1.0, 3.0, 5.0, 7.0, 9.0])
    assert (fit.slope, fit.low, fit.high) == (2.0, 2.0, 2.0)


def test_theil_sen_interval_covers_the_true_slope_about_95_percent_of_the_time():
    rng = random.Random(7)
    covered = 0
    trials = 300
    for _ in range(trials):
        xs = [float(i) for i in range(25)]
        ys = [0.3 * x + rng.gauss(0, 2) for x in xs]
        fit = theil_sen(xs, ys)
        covered += fit.low <= 0.3 <= fit.high
    assert 0.90 <= covered / trials <= 0.99


def test_theil_sen_refuses_a_single_x():
    with pytest.raises(ValueError):
        theil_sen([1.0, 1.0], [2.0, 3.0])


def test_mann_kendall_textbook_values():
    # y = 1..5: S = 10, Var(S) = 5·4·15/18, z = (S − 1)/σ = 2.2045, two-sided p = 0.0275
    mk = mann_kendall([1, 2, 3, 4, 5])
    assert mk.s == 10 and mk.variance == pytest.approx(16.6667, rel=1e-4)
    assert mk.z == pytest.approx(2.2045, rel=1e-4)
    assert mk.p == pytest.approx(0.0275, abs=1e-4)
    assert mk.tau == 1.0
    # ties: [1, 1, 2] has S = 2, Var = (3·2·11 − 1·2·2·... ) / 18 with one tie of 2: (66 − 18) / 18
    tied = mann_kendall([1, 1, 2])
    assert tied.s == 2 and tied.variance == pytest.approx((66 - 18) / 18)


def test_mann_kendall_finds_no_trend_in_noise_and_one_in_a_slow_rise():
    rng = random.Random(3)
    flat = [rng.gauss(10, 1) for _ in range(60)]
    assert mann_kendall(flat).p_increasing > 0.01
    rising = [10 + 0.05 * i + rng.gauss(0, 1) for i in range(60)]
    assert mann_kendall(rising).p_increasing < 0.01


def test_thin_bounds_the_points_and_keeps_the_slope():
    xs = [float(i) for i in range(2000)]
    ys = [3.0 * x for x in xs]
    tx, ty = thin(xs, ys, 200)
    assert len(tx) <= 200
    assert theil_sen(tx, ty).slope == pytest.approx(3.0)
    fit = theil_sen(tx, ty)
    assert residual_spread(tx, ty, fit) == pytest.approx(0.0, abs=1e-6)


def test_sketch_agrees_with_the_exact_percentile_on_real_looking_latencies():
    rng = random.Random(11)
    values = [rng.expovariate(1 / 0.4) + 0.1 for _ in range(5000)]
    sketch = LatencySketch(values)
    for q in (50, 99):
        assert sketch.quantile(q) == pytest.approx(percentile(values, q), rel=0.03)
