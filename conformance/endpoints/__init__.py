"""Reference endpoints: a bundled AI Box and a robot simulator.

The box:

* :mod:`.behaviour` — the box's decisions, sans-I/O (tables, cached answers);
* :mod:`.connection` — one TCP connection, sans-I/O (framing and the stream's fast path);
* :mod:`.protocols` — the connections on asyncio (TCP and UDP protocols, admission, idle sweep);
* :mod:`.server` — :class:`ReferenceBox`, the box over asyncio TCP + UDP;
* :mod:`.framelog` — ``--log FILE``, one JSON line per frame in and out;
* :mod:`.loop` — event-loop helpers and :class:`BoxThread`, a box for synchronous code;
* :mod:`.serve` — the ``isight-conformance serve`` command's body (its parser: :mod:`conformance.commands.serve`);
* :mod:`.bundled` — the box a run starts on loopback when it names no target.

The robot (``isight-conformance robot``):

* :mod:`.robot_steps` — the canonical sessions S1/E4 as data, sans-I/O: each step, the answer it
  expects and the judge that reads it; :class:`RobotFaults` for deliberately broken robots;
* :mod:`.robot_result` — :class:`RobotResult`, what a session did (exit code, timeline, figures);
* :mod:`.robot_io` — its connections, clock and record on asyncio;
* :mod:`.robot` — :class:`RobotSession`, the asyncio driver that plays the steps.

The primer trajectory the simulated robot streams is :mod:`conformance.harness.trajectory`.
"""

from ..harness.trajectory import PrimerTrajectory, RoundedRectangle
from .behaviour import BoxBehaviour, BoxConfig, Cycle, Decision, Reaction
from .box_connection import BoxConnection
from .framelog import FrameLog
from .loop import BoxThread
from .robot import RobotSession, parse_target, run_robot
from .robot.robot_result import RobotResult, TimelineEntry
from .robot.robot_steps import RobotFaults
from .server import ReferenceBox

__all__ = [
    "BoxBehaviour", "BoxConfig", "BoxConnection", "BoxThread", "Cycle", "Decision", "FrameLog", "PrimerTrajectory",
    "Reaction", "ReferenceBox", "RobotFaults", "RobotResult", "RobotSession", "RoundedRectangle", "TimelineEntry",
    "parse_target", "run_robot",
]
