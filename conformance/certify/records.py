"""What ``certify-robot`` is told and what a run recorded: the settings and the run.

The sessions, connections and exchanges themselves are the shared model of observed
traffic (:mod:`conformance.observed.connections`), which ``analyze`` builds too.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..endpoints.behaviour import BoxConfig
from ..observed.connections import SessionRecord
from ..observed.stream_timing import check_tolerances
from ..protocol import DEFAULT_PORT, DEFAULT_PROFILE, Profile, ResultCode
from ..runtime.settings import DEFAULT_SEED
from .latency import AnswerLatency, check_range, default_range_ms

#: ``--inject`` choices: box behaviours that show how the robot copes (INFORMATIONAL).
INJECTIONS: dict[str, str] = {
    "not-ready": "CycleOn is answered 0001 (box not ready, S2)",
    "slow": "every answer is held back to 80 % of time_out (T1)",
    "busy": "the vision result request is answered 202 (busy, E3)",
    "close-mid-cycle": "the box closes the command connection right after answering CycleOn",
}
#: ``slow``: answers are held back by this share of ``time_out``.
SLOW_SHARE = 0.8

@dataclass(frozen=True)
class CertifyConfig:
    """Everything one ``certify-robot`` run needs (the CLI builds it from its flags)."""

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    udp: bool = True
    profile: Profile = DEFAULT_PROFILE
    #: sessions to judge before ending on its own
    sessions: int = 1
    #: seconds to wait for the robot to connect (each session), and the longest silence of a session
    wait_s: float = 120.0
    #: seconds the other connections may stay open after the command connection closed
    linger_s: float = 5.0
    #: seconds after the last close of a session with no command connection before it ends
    grace_s: float = 1.0
    #: a session is cut off after this many seconds
    max_session_s: float = 600.0
    #: judge the revision's session (E4): True forced on, False S1 only, None (auto) each session by what the
    #: robot sends (ProgIdx or the result request: E4, else S1)
    extension: bool | None = None
    inject: tuple[str, ...] = ()
    #: CycleOn, CycleOff and the result request are answered after a latency drawn from this range (ms), as a
    #: real box takes time to start and stop a detection; None: the default (:func:`.latency.default_range_ms`);
    #: (0, 0): at once
    answer_latency_ms: tuple[float, float] | None = None
    #: the seed of the latencies' draws (a run repeats with its seed)
    seed: int = DEFAULT_SEED
    #: T2: mean and windowed rate within this share of the declared rate
    rate_tolerance: float = 0.10
    #: T2: p99 |interval - period| within this share of the period
    jitter_tolerance: float = 0.50
    report_dir: Path | None = None
    pcap_dir: Path | None = None
    command: str = ""
    #: the acceptance package's run ID, device under test and tester (Acceptance.to_dict()), for the reports
    acceptance: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        unknown = [i for i in self.inject if i not in INJECTIONS]
        if unknown:
            raise ValueError(f"unknown --inject {', '.join(unknown)}; choose from {', '.join(INJECTIONS)}")
        if not 0 <= self.port <= 65535:
            raise ValueError(f"port must be 0..65535, not {self.port}")
        if not 1 <= self.sessions <= 1000:
            raise ValueError(f"--sessions must be 1..1000, not {self.sessions}")
        for name in ("wait_s", "linger_s", "grace_s", "max_session_s"):
            if not 0 < getattr(self, name) <= 86_400:
                raise ValueError(f"{name} must be in (0, 86400] seconds, not {getattr(self, name)}")
        check_tolerances(self.rate_tolerance, self.jitter_tolerance)
        check_range(self.latency_range_ms, self.profile)

    @property
    def latency_range_ms(self) -> tuple[float, float]:
        return default_range_ms(self.profile) if self.answer_latency_ms is None else self.answer_latency_ms

    def latency_text(self) -> str:
        """How this run's answers were timed, for the report."""
        if self.slow_delay_s:
            return f"every answer held back {self.slow_delay_s * 1000:.0f} ms (--inject slow)"
        return self.answer_latency().describe()

    def answer_latency(self) -> AnswerLatency:
        """The run's latencies (``--inject slow`` holds every answer instead: no latency of its own then)."""
        return AnswerLatency((0.0, 0.0) if "slow" in self.inject else self.latency_range_ms, self.seed)

    @property
    def slow_delay_s(self) -> float:
        return SLOW_SHARE * self.profile.time_out_s if "slow" in self.inject else 0.0

    def box_config(self) -> BoxConfig:
        """The reference box's knobs for this run (the box always implements 26/27)."""
        return BoxConfig(
            profile=self.profile,
            not_ready="not-ready" in self.inject,
            vision_result=ResultCode.BUSY if "busy" in self.inject else ResultCode.OK,
            extension=True,
        )


@dataclass
class RunRecord:
    config: CertifyConfig
    t_start: float
    t_end: float
    host: str
    tcp_port: int
    udp_port: int | None
    sessions: list[SessionRecord]
    end_reason: str  # "complete", "wait", "interrupted"
    end_note: str = ""
    refused: int = 0
    #: the suite's own failures (exceptions in callbacks): each becomes an ERROR case
    errors: list[str] = field(default_factory=list)


def monotonic_wall() -> Callable[[], float]:
    """A clock that reads like ``time.time()`` but never jumps (perf_counter since now)."""
    t0_wall, t0 = time.time(), time.perf_counter()
    return lambda: t0_wall + (time.perf_counter() - t0)
