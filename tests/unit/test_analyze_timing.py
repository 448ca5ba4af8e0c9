"""T2 from a capture (conformance/analyze/capture_timing.py): the robot's rate and jitter in blocks
(certify-robot's judgement), the box's backlog (the active suite's figure)."""

from __future__ import annotations

from conformance.analyze.capture_timing import PoseClock, backlog
from conformance.analyze.findings import Series


def clock(times, block=100, **kw):
    c = PoseClock(50.0, kw.get("rate", 0.1), kw.get("jitter", 0.5), Series(), block=block)
    for t in times:
        c.add(t)
    return c


def test_a_steady_stream_passes_in_every_block():
    c = clock([i * 0.02 for i in range(350)])
    j = c.finish()
    assert j.ok and j.poses == 350 and j.blocks == 4
    assert c.intervals.n == 349  # every interval, across the block boundaries too


def test_a_drifting_clock_fails_the_rate_in_a_later_block():
    times, t = [], 0.0
    for i in range(400):
        times.append(t)
        t += 0.02 * (1 + i / 200)  # the period grows to 3x
    j = clock(times).finish()
    assert not j.rate_ok
    assert "off the declared" in j.rate_text or "windows outside" in j.rate_text


def test_a_bursty_stream_fails_the_jitter():
    times = [(i // 5) * 0.1 + (i % 5) * 0.0001 for i in range(200)]
    j = clock(times).finish()
    assert not j.jitter_ok and "arrived together" in j.jitter_text


def test_a_gap_is_not_an_interval():
    c = clock([i * 0.02 for i in range(50)], block=1000)
    c.cut()
    for i in range(50):
        c.add(10.0 + i * 0.02)
    j = c.finish()
    assert j.ok and j.blocks == 2 and j.poses == 100
    assert c.intervals.max < 25


def test_backlog():
    flat, growing, few = Series(), Series(), Series()
    for i in range(400):
        flat.add(1.0)
        growing.add(1.0 + i)
    for _ in range(5):
        few.add(1.0)
    assert not backlog(flat, 50).grows
    b = backlog(growing, 50)
    assert b.grows and b.last_p50_ms > b.threshold_ms > b.first_p50_ms
    assert backlog(few, 50) is None
