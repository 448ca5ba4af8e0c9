"""``certify-robot``: the suite as the AI Box, judging a robot (client) implementation.

Like Autobahn's fuzzingserver or h2specd, the suite listens, answers the robot with the
reference box's logic and judges what the robot does against PROTOCOL.md's client-side
reading:

* :mod:`.records` — the settings and what a run records (sessions, connections, exchanges);
* :mod:`.listener` — the asyncio TCP/UDP server: sessions, bounded waits, UDP;
* :mod:`.connection` — one robot connection: answers (the reference box's logic), injects, records;
* :mod:`.traffic` — the robot's bytes decoded from the transcripts, the F4 heuristic, wire logs;
* :mod:`.session` — canonical-order tracking (S1/E4) and awaited answers (A1/T1);
* :mod:`.timing` — stream rate and send-interval jitter (T2);
* :mod:`.catalogue` — the cases: stable IDs, clauses, levels, acceptable outcomes;
* :mod:`.checks` — the judgments (CaseResults with their evidence);
* :mod:`.runner` — one run end to end (:func:`certify`); :mod:`.cli` — the command.
"""

from .checks import catalogue, judge
from .listener import CertifyListener
from .records import INJECTIONS, CertifyConfig, RunRecord
from .runner import CertifyOutcome, certify

__all__ = ["INJECTIONS", "CertifyConfig", "CertifyListener", "CertifyOutcome", "RunRecord", "catalogue", "certify",
           "judge"]
