"""``certify-robot``: the suite as the AI Box, judging a robot (client) implementation.

Like Autobahn's fuzzingserver or h2specd, the suite listens, answers the robot with the
reference box's logic and judges what the robot does against PROTOCOL.md's client-side
reading:

* :mod:`.records` — the settings and the run's record;
* :mod:`.listener` — the asyncio TCP/UDP server: sessions, bounded waits, UDP;
* :mod:`.connection` — one robot connection: answers (the reference box's logic), injects, records;
* :mod:`.checks` — the judgments (CaseResults with their evidence); :mod:`.wire` — the wire logs they quote;
* :mod:`.runner` — one run end to end (:func:`certify`); the command is :mod:`conformance.commands.certify_robot`.

What it records and judges from (sessions, connections, the robot's frames, the session
view, the stream's rate and jitter, the case catalogue) is the shared model of observed
traffic, :mod:`conformance.observed`, which ``analyze`` builds on too.
"""

from .certification import CertifyOutcome, certify
from .checks import catalogue, judge
from .listener import CertifyListener
from .records import INJECTIONS, CertifyConfig, RunRecord

__all__ = ["INJECTIONS", "CertifyConfig", "CertifyListener", "CertifyOutcome", "RunRecord", "catalogue", "certify",
           "judge"]
