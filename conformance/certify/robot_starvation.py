"""Could the robot's own starvation explain a FAIL? (``certify-robot`` on a loaded runner.)

A robot simulated on the suite's own host (a loopback address) shares its CPUs: when they are
contended the robot sends late, and its stream's rate or jitter can breach T2 although its
program is right. The suite's gauge cannot see the robot's stalls, but the host's CPU pressure
(Linux PSI, sampled by :mod:`conformance.harness.starvation`'s gauge) can: when some task waited
for a CPU during the stream at least as long as the breach, the FAIL says so. The verdict stands
(a controller runs on its own CPU, and a rate breach is never INCONCLUSIVE); the note tells the
reader to rerun on a quiet machine before blaming the robot. A robot elsewhere gets no note.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..harness.starvation import StarvationGauge, gauge, is_loopback
from ..observed.stream_timing import PSI_MARGIN_S

#: the words every such note carries (benchmarks/bench_certify_loaded.py counts them)
ROBOT_STARVED = "the robot's own starvation could explain it"


def robot_starved_note(excess_ms: float, times: Sequence[float], host: str, source: StarvationGauge | None = None) -> str:
    """The note for a T2 FAIL breaching by ``excess_ms`` over the stream ``times`` (wall clock) from ``host``,
    or "" when the robot is not on this host or the host's CPU was not contended that long."""
    if excess_ms <= 0 or not times or not is_loopback(host):
        return ""
    stall = (source or gauge()).host_stall_ms(min(times) - PSI_MARGIN_S, max(times) + PSI_MARGIN_S, wall=True)
    if stall < excess_ms:
        return ""
    return (f"; {ROBOT_STARVED}: it runs on this host (a loopback address) and the host's CPU was contended during "
            f"the stream (Linux PSI: some task waited {stall:.0f} ms for a CPU; the breach is {excess_ms:.1f} ms). "
            "The verdict stands (a controller has its own CPU): rerun on a quiet machine before blaming the robot")
