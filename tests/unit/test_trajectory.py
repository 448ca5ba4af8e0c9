"""The primer trajectory: deterministic, smooth, closed, finite, in plausible units."""

import math

import pytest

from conformance.harness.trajectory import PrimerTrajectory, RoundedRectangle

pytestmark = pytest.mark.timeout(30)


def test_deterministic():
    a, b = PrimerTrajectory(), PrimerTrajectory()
    assert [a.pose_at(t / 7) for t in range(20)] == [b.pose_at(t / 7) for t in range(20)]


def test_starts_and_ends_at_home():
    traj = PrimerTrajectory(duration=3.0)
    home = traj.home
    assert traj.pose_at(-1.0) == home
    assert traj.pose_at(0.0) == home
    for got, want in zip(traj.pose_at(3.0), home):
        assert got == pytest.approx(want, abs=1e-9)
    assert traj.pose_at(99.0) == traj.pose_at(3.0)
    # home is above the path start, tool straight down (FANUC W, P, R = 180, 0, 0)
    assert home[2] == pytest.approx(traj.z + traj.approach)
    assert home[3:] == pytest.approx((180.0, 0.0, 0.0))


@pytest.mark.parametrize("duration", [0.5, 2.0, 10.0])
def test_smooth_at_50_hz(duration):
    traj = PrimerTrajectory(duration=duration)
    samples = list(traj.samples(50.0))
    assert len(samples) == int(duration * 50) + 1
    peak_speed = 0.0
    for (t0, p0), (t1, p1) in zip(samples, samples[1:]):
        assert all(math.isfinite(v) for v in p1)
        step = math.dist(p0[:3], p1[:3])
        peak_speed = max(peak_speed, step / (t1 - t0))
        # orientation never jumps (no wrap-around): the lean is at most tilt degrees
        assert max(abs(a - b) for a, b in zip(p0[3:], p1[3:])) <= 2 * traj.tilt
    # the path length over the loop's share of the time, with the cosine ease's pi/2 peak factor
    loop_time = duration * (1 - 2 * traj.approach_share)
    assert peak_speed <= traj.path.length / loop_time * math.pi / 2 * 1.05


def test_covers_the_rounded_rectangle():
    traj = PrimerTrajectory(duration=2.0)
    xs = [p[0] for _, p in traj.samples(500.0)]
    ys = [p[1] for _, p in traj.samples(500.0)]
    path = traj.path
    assert min(xs) == pytest.approx(path.cx - path.width / 2, abs=0.5)
    assert max(xs) == pytest.approx(path.cx + path.width / 2, abs=0.5)
    assert min(ys) == pytest.approx(path.cy - path.height / 2, abs=0.5)
    assert max(ys) == pytest.approx(path.cy + path.height / 2, abs=0.5)


def test_rounded_rectangle_geometry():
    rect = RoundedRectangle(cx=0.0, cy=0.0, width=100.0, height=60.0, radius=10.0)
    assert rect.length == pytest.approx(2 * 80 + 2 * 40 + 2 * math.pi * 10)
    x, y, heading = rect.point(0.0)
    assert (x, y, heading) == pytest.approx((0.0, -30.0, 0.0))
    # continuous everywhere, including the joins between lines and arcs
    n = 2000
    points = [rect.point(rect.length * i / n) for i in range(n)]
    for a, b in zip(points, points[1:]):
        assert math.dist(a[:2], b[:2]) <= rect.length / n * 1.001
        assert 0 <= b[2] - a[2] < 1.0  # the heading rises steadily
    assert math.dist(points[-1][:2], points[0][:2]) <= rect.length / n * 1.001  # closed
    assert rect.point(rect.length)[:2] == pytest.approx(points[0][:2], abs=1e-9)
    # every point lies on the rectangle's outline
    for x, y, _ in points:
        assert abs(x) <= 50 + 1e-9 and abs(y) <= 30 + 1e-9
        assert abs(abs(x) - 50) < 1e-6 or abs(abs(y) - 30) < 1e-6 or math.dist((abs(x), abs(y)), (40, 20)) == pytest.approx(10)


def test_sharp_corners_and_validation():
    rect = RoundedRectangle(width=10, height=10, radius=0)
    assert rect.length == pytest.approx(40)
    with pytest.raises(ValueError):
        RoundedRectangle(width=10, height=10, radius=6)
    with pytest.raises(ValueError):
        RoundedRectangle(width=0)
    with pytest.raises(ValueError):
        PrimerTrajectory(duration=0)
    with pytest.raises(ValueError):
        list(PrimerTrajectory().samples(0))
