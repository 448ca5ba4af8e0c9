"""Before a run: would lanes pay, and may they be used? (``run --lanes auto``)

Two connections are opened; NONE is asked on the second while the first stays open (S4: a
box serves several connections at once), then twice more, and the round trips are timed.
Lanes are used only on positive evidence that the box serves two connections at once, and
only when its answers are slow enough that running cases side by side saves more than
starting the workers costs. The probe's NONE requests change no state; it is not a case and
judges nothing (a box that fails it is simply run one case at a time).
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass

from ..protocol import Profile
from .client import Answer, TcpConnection
from .liveness import PROBE_NONE
from .target import Target, Unreachable
from .transcript import Transcript

#: a box answering faster than this is run one case at a time (a worker costs ~1.5 s of CPU to start)
SLOW_MS = 20.0
#: the probe's own bound per answer (a box slower than this is run one case at a time)
PROBE_WAIT_S = 2.0


@dataclass(frozen=True)
class LaneProbe:
    concurrent: bool  # a second connection was answered while the first stayed open
    round_trip_ms: float | None  # the median of the NONE round trips on the second connection
    why: str

    def lanes(self, wanted: int) -> int:
        slow = self.round_trip_ms is not None and self.round_trip_ms >= SLOW_MS
        return wanted if self.concurrent and slow else 1


def probe_lanes(target: Target, profile: Profile, time_out_s: float) -> LaneProbe:
    """Never raises: a box that does not answer both connections gets ``concurrent=False``."""
    wait = min(PROBE_WAIT_S, time_out_s)
    transcript = Transcript(case_id="lanes-probe")
    first = TcpConnection(transcript, target, profile, "lanes-first", wait)
    second = TcpConnection(transcript, target, profile, "lanes-second", wait)
    try:
        first.connect()
        second.connect()
        rtts = []
        for _ in range(3):
            got = second.request(PROBE_NONE, "lanes probe: NONE on a second connection while the first is open")
            if not isinstance(got, Answer):
                return LaneProbe(False, None, f"a second connection was not answered ({got.describe()})")
            rtts.append(got.latency_s * 1000)
        on_first = first.request(PROBE_NONE, "lanes probe: NONE on the first connection")
        if not isinstance(on_first, Answer):
            return LaneProbe(False, None, f"the first connection was not answered ({on_first.describe()})")
    except Unreachable as exc:
        return LaneProbe(False, None, f"could not open two connections ({exc})")
    finally:
        first.close()
        second.close()
        transcript.close()
    rtt = statistics.median(rtts)
    return LaneProbe(True, rtt, f"serves two connections at once; answers NONE in {rtt:.0f} ms")
