"""The robot simulator: one package for its driver and its parts.

- :mod:`.robot_session`: :class:`RobotSession`, the driver over asyncio (``run_robot``, ``parse_target``);
- :mod:`.robot_io`: what every step shares (the connections, waits, teardown);
- :mod:`.robot_steps`: the canonical sessions as data (S1, E4) and :class:`RobotFaults`;
- :mod:`.robot_result`: what a session did (:class:`RobotResult`, its timeline and figures).
"""

from .robot_result import RobotResult, TimelineEntry
from .robot_session import RobotSession, parse_target, run_robot
from .robot_steps import RobotFaults

__all__ = ["RobotFaults", "RobotResult", "RobotSession", "TimelineEntry", "parse_target", "run_robot"]
