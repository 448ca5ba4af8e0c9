"""A plausible primer trajectory for the robot simulator (deterministic, smooth).

The robot of the iSight installation primes the edge of a part (e.g. a windscreen)
before bonding: the tool approaches from above, runs one bead around a rounded
rectangle at constant height, and lifts off. :class:`PrimerTrajectory` gives that
path as a pose ``(x, y, z, w, p, r)`` in millimetres and degrees (FANUC WPR) for any
time, with an eased speed profile (zero speed at start and end, no jumps) so that a
pose stream sampled from it looks like a real controller's.

Everything is a pure function of time and the parameters: the same call always
gives the same pose, which makes sessions reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

Pose = tuple[float, float, float, float, float, float]


def _ease(u: float) -> float:
    """Cosine ease-in/ease-out on [0, 1]: zero slope at both ends."""
    u = min(1.0, max(0.0, u))
    return (1.0 - math.cos(math.pi * u)) / 2.0


@dataclass(frozen=True)
class RoundedRectangle:
    """A closed path in the XY plane: width × height mm, corner radius mm, centred on (cx, cy).

    The path starts in the middle of the bottom edge and runs counter-clockwise.
    """

    cx: float = 800.0
    cy: float = 0.0
    width: float = 300.0
    height: float = 200.0
    radius: float = 40.0

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError("width and height must be positive")
        if not 0 <= self.radius <= min(self.width, self.height) / 2:
            raise ValueError("radius must be between 0 and half the shorter side")

    @property
    def _straights(self) -> tuple[float, float]:
        return self.width - 2 * self.radius, self.height - 2 * self.radius

    @property
    def length(self) -> float:
        sx, sy = self._straights
        return 2 * sx + 2 * sy + 2 * math.pi * self.radius

    def point(self, s: float) -> tuple[float, float, float]:
        """``(x, y, heading in degrees)`` at arc length ``s`` (taken modulo the length).

        The heading is the tangent direction, continuous and rising from 0 to 360
        over one loop.
        """
        total = self.length
        s = s % total if total else 0.0
        sx, sy = self._straights
        r = self.radius
        quarter = math.pi * r / 2
        # segments: half bottom, corner, right, corner, top, corner, left, corner, half bottom
        segments: list[tuple[str, float, float]] = [
            ("line", sx / 2, 0.0), ("arc", quarter, 0.0), ("line", sy, 90.0), ("arc", quarter, 90.0),
            ("line", sx, 180.0), ("arc", quarter, 180.0), ("line", sy, 270.0), ("arc", quarter, 270.0),
            ("line", sx / 2, 360.0),
        ]
        # starting point of each segment, walked once (nine segments: cheap)
        x, y = self.cx, self.cy - self.height / 2
        last = len(segments) - 1
        for n, (kind, seg_len, heading) in enumerate(segments):
            if s <= seg_len or n == last:
                if kind == "line":
                    rad = math.radians(heading)
                    return x + s * math.cos(rad), y + s * math.sin(rad), heading
                # arc turning left by 90 degrees
                angle = s / r if r else 0.0
                start = math.radians(heading - 90.0)  # from the corner centre to the start point
                ccx, ccy = x - r * math.cos(start), y - r * math.sin(start)
                return (
                    ccx + r * math.cos(start + angle),
                    ccy + r * math.sin(start + angle),
                    heading + math.degrees(angle),
                )
            # advance to the end of this segment
            if kind == "line":
                rad = math.radians(heading)
                x, y = x + seg_len * math.cos(rad), y + seg_len * math.sin(rad)
            else:
                start = math.radians(heading - 90.0)
                ccx, ccy = x - r * math.cos(start), y - r * math.sin(start)
                x, y = ccx + r * math.cos(start + math.pi / 2), ccy + r * math.sin(start + math.pi / 2)
            s -= seg_len
        return x, y, 360.0  # pragma: no cover (the last line segment always returns)


@dataclass(frozen=True)
class PrimerTrajectory:
    """Approach, one bead around a rounded rectangle, lift-off; ``duration`` seconds in all.

    ``pose_at(t)`` for ``t <= 0`` is the home pose (above the start point), for
    ``t >= duration`` the home pose again; in between the tool comes down by
    ``approach`` mm (first ``approach_share`` of the time), runs the loop at height
    ``z`` and goes back up. W, P, R are the usual FANUC tool-down orientation
    (180, 0, 0) with a small drag angle (``tilt``) against the direction of travel,
    as a primer nozzle would lean: smooth, since the corners are rounded.
    """

    duration: float = 2.0
    path: RoundedRectangle = RoundedRectangle()
    z: float = 250.0
    approach: float = 50.0
    approach_share: float = 0.1
    tilt: float = 5.0

    def __post_init__(self) -> None:
        if not self.duration > 0:
            raise ValueError("duration must be positive")
        if not 0 < self.approach_share < 0.5:
            raise ValueError("approach_share must be in (0, 0.5)")

    @property
    def home(self) -> Pose:
        return self.pose_at(0.0)

    def pose_at(self, t: float) -> Pose:
        """The pose at time ``t`` seconds after the start of the trajectory."""
        u = min(1.0, max(0.0, t / self.duration))
        a = self.approach_share
        if u < a:  # coming down above the start point
            s, lift = 0.0, 1.0 - _ease(u / a)
        elif u > 1.0 - a:  # lifting off at the start point (the loop is closed)
            s, lift = self.path.length, _ease((u - (1.0 - a)) / a)
        else:
            s, lift = self.path.length * _ease((u - a) / (1.0 - 2 * a)), 0.0
        x, y, heading = self.path.point(s)
        # the nozzle leans by ``tilt`` degrees against the direction of travel (a drag
        # angle), eased in and out with the approach so that home is tool-straight-down
        lean = self.tilt * (1.0 - lift)
        rad = math.radians(heading)
        return (x, y, self.z + self.approach * lift, 180.0 - lean * math.sin(rad), lean * math.cos(rad), 0.0)

    def samples(self, rate_hz: float) -> Iterator[tuple[float, Pose]]:
        """``(t, pose)`` at ``rate_hz`` from 0 to ``duration`` inclusive."""
        if not rate_hz > 0:
            raise ValueError("rate must be positive")
        count = int(math.floor(self.duration * rate_hz + 1e-9))
        for i in range(count + 1):
            t = i / rate_hz
            yield t, self.pose_at(t)
