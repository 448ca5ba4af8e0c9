"""T2 from the robot's side on synthetic arrival times: rate, windows (drift), jitter (bursts)."""

from __future__ import annotations

import math

import pytest

from conformance.observed.stream_timing import MIN_POSES, judge_jitter, judge_rate, stream_stats

RATE = 50.0
T = 1 / RATE


def steady(n: int, period: float = T, start: float = 100.0) -> list[float]:
    return [start + i * period for i in range(n)]


def bursty(n: int, burst: int) -> list[float]:
    return [100.0 + (i // burst) * burst * T + (i % burst) * 1e-5 for i in range(n)]


def drifting(n: int, drift_per_s: float) -> list[float]:
    times, t, period = [], 100.0, T
    for _ in range(n):
        times.append(t)
        t += period * (1 + drift_per_s * (t - 100.0))
    return times


def test_too_few_poses():
    assert stream_stats([], RATE) is None
    assert stream_stats(steady(MIN_POSES - 1), RATE) is None
    assert stream_stats(steady(MIN_POSES), RATE) is not None


def test_a_steady_stream_passes_both():
    stats = stream_stats(steady(200), RATE)
    assert stats is not None
    assert stats.poses == 200 and len(stats.intervals_ms) == 199
    assert stats.mean_rate_hz == pytest.approx(RATE)
    assert stats.dev_p99_ms == pytest.approx(0, abs=1e-6) and stats.together == 0
    assert len(stats.windows) == 4 and all(w.rate_hz == pytest.approx(RATE) for w in stats.windows)
    ok, text = judge_rate(stats, 0.1)
    assert ok and "within 45.00–55.00 Hz" in text
    ok, text = judge_jitter(stats, 0.5)
    assert ok and "allowed 10.00 ms" in text
    assert "200 poses" in stats.describe()


def test_a_stream_at_another_rate_fails_rate_not_jitter_when_the_jitter_tolerance_is_wide():
    stats = stream_stats(steady(100, period=1 / 40), RATE)  # 40 Hz declared as 50
    assert stats is not None
    ok, text = judge_rate(stats, 0.1)
    assert not ok and "-20.0 %" in text and "mean stream rate 40.00 Hz" in text


def test_a_drifting_clock_fails_on_its_windows():
    stats = stream_stats(drifting(150, 0.3), RATE)
    assert stats is not None
    ok, text = judge_rate(stats, 0.1)
    assert not ok
    assert stats.windows[0].rate_hz > stats.windows[-1].rate_hz
    assert "window" in text or "mean" in text


def test_drift_with_a_good_mean_is_caught_by_the_windows():
    # first half fast, second half slow: the mean is right, the windows are not
    times = steady(100, period=T * 0.8) + steady(100, period=T * 1.2, start=100.0 + 100 * T * 0.8)
    stats = stream_stats(times, RATE)
    assert stats is not None
    assert abs(stats.mean_rate_hz - RATE) / RATE < 0.1
    ok, text = judge_rate(stats, 0.1)
    assert not ok and "one-second windows outside" in text


def test_bursts_keep_the_rate_and_fail_jitter():
    stats = stream_stats(bursty(200, 5), RATE)
    assert stats is not None
    assert judge_rate(stats, 0.1)[0]
    ok, text = judge_jitter(stats, 0.5)
    assert not ok
    assert stats.together == 160
    assert stats.dev_p99_ms == pytest.approx(80, abs=0.1)
    assert "(bursts)" in text


def test_the_jitter_limit_is_p99_not_max():
    times = steady(300)
    times[150] += 0.015  # one 15 ms hiccup (two intervals off by 15 ms) in 299
    stats = stream_stats(times, RATE)
    assert stats is not None
    assert stats.dev_max_ms == pytest.approx(15, abs=1e-6)
    assert judge_jitter(stats, 0.5)[0]


def test_simultaneous_poses_do_not_divide_by_zero():
    stats = stream_stats([1.0, 1.0, 1.0, 1.0], RATE)
    assert stats is not None
    assert math.isinf(stats.mean_rate_hz)
    assert not judge_rate(stats, 0.1)[0]
    assert not judge_jitter(stats, 0.5)[0]


def test_unsorted_times_are_sorted():
    times = steady(50)
    stats = stream_stats(list(reversed(times)), RATE)
    assert stats is not None and stats.mean_rate_hz == pytest.approx(RATE)


def _jittery(start: float) -> list[float]:
    """150 poses at 50 Hz, every tenth sent 15 ms late (the next one on time): p99 jitter 15 ms."""
    return [start + i * 0.02 + (0.015 if i % 10 == 5 else 0.0) for i in range(150)]


def _gauge_with_pressure(monkeypatch, start: float, us_per_sample: int):
    from conformance.harness.starvation import StarvationGauge
    from conformance.observed import stream_timing

    g = StarvationGauge()
    for i in range(80):  # samples every 50 ms from before the stream to after it (wall clock)
        g.note_pressure(i * 0.05, start - 0.5 + i * 0.05, i * us_per_sample)
    monkeypatch.setattr(stream_timing, "gauge", lambda: g)


def test_a_local_robots_jitter_under_host_cpu_contention_is_not_judged(monkeypatch):
    from conformance.observed.stream_timing import jitter_starved

    times = _jittery(5000.0)
    stats = stream_stats(times, 50.0)
    _gauge_with_pressure(monkeypatch, 5000.0, 45_000)  # 45 of every 50 ms some task waited for a CPU
    reason = jitter_starved(stats, times, 0.25, peer_local=True)
    assert reason is not None and "loopback" in reason and "PSI" in reason
    assert jitter_starved(stats, times, 0.25, peer_local=False) is None  # a robot elsewhere: the breach stands


def test_a_local_robots_jitter_on_a_quiet_host_still_fails(monkeypatch):
    from conformance.observed.stream_timing import jitter_starved

    times = _jittery(5000.0)
    stats = stream_stats(times, 50.0)
    _gauge_with_pressure(monkeypatch, 5000.0, 200)  # 0.4 % contention
    assert not judge_jitter(stats, 0.25)[0]
    assert jitter_starved(stats, times, 0.25, peer_local=True) is None


def test_a_latency_growing_two_ms_a_pose_is_a_backlog_whatever_its_base() -> None:
    from conformance.suite.pose_stream import StreamResult

    for base in (2.0, 20.0, 100.0):  # the box's own latency before the backlog starts
        growing = StreamResult(rate_hz=50.0, latencies_ms=[base + 2.0 * i for i in range(150)])
        first, last, bar = growing.backlog()
        assert last > bar, (base, first, last, bar)


def test_a_steady_latency_with_load_noise_is_no_backlog() -> None:
    from conformance.suite.pose_stream import StreamResult

    for base in (2.0, 20.0, 100.0):
        noisy = [base + (7.0 if i % 3 == 0 else 0.0) + (15.0 if i > 140 else 0.0) for i in range(150)]
        first, last, bar = StreamResult(rate_hz=50.0, latencies_ms=noisy).backlog()
        assert last <= bar, (base, first, last, bar)
