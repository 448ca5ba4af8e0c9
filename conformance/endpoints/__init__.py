"""Reference endpoints: a bundled AI Box and a robot simulator.

* :mod:`.behaviour` — the box's decisions, sans-I/O (tables, cached answers, a fast path);
* :mod:`.box` — the box over asyncio TCP + UDP (``isight-conformance serve``),
  :class:`ReferenceBox` for async code and :class:`BoxThread` for synchronous code;
* :mod:`.robot` — the canonical robot session S1/E4 (``isight-conformance robot``),
  :class:`RobotSession` with :class:`RobotFaults` for deliberately broken robots;
* :mod:`.trajectory` — the primer trajectory the simulated robot streams.
"""

from ..trajectory import PrimerTrajectory, RoundedRectangle
from .behaviour import BoxBehaviour, BoxConfig, BoxConnection, Cycle, Decision, Reaction
from .box import BoxThread, FrameLog, ReferenceBox
from .robot import RobotFaults, RobotResult, RobotSession, TimelineEntry, parse_target, run_robot

__all__ = [
    "BoxBehaviour", "BoxConfig", "BoxConnection", "BoxThread", "Cycle", "Decision", "FrameLog", "PrimerTrajectory",
    "Reaction", "ReferenceBox", "RobotFaults", "RobotResult", "RobotSession", "RoundedRectangle", "TimelineEntry",
    "parse_target", "run_robot",
]
