"""What one analysis shares: its settings, the judging profile, the findings and figures."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..observed.robot_frames import judge_profile
from ..observed.stream_timing import check_tolerances
from ..protocol import DEFAULT_PORT, DEFAULT_PROFILE, Profile
from .findings import Findings, Series
from .judging import Cycles

__all__ = ["AnalyzeConfig", "Context", "Stats"]


@dataclass(frozen=True)
class AnalyzeConfig:
    """The settings of one ``analyze`` run (the CLI builds it from its flags)."""

    profile: Profile = DEFAULT_PROFILE
    #: iSight's TCP/UDP ports: a conversation with one of them on one side is iSight, that side is the box
    ports: tuple[int, ...] = (DEFAULT_PORT,)
    #: also find iSight conversations on other ports by their content (as the Wireshark dissector does)
    heuristic: bool = True
    #: the UDP CRC algorithm was stated (--crc): a CRC that fits another algorithm is then a FAIL, not INCONCLUSIVE
    crc_stated: bool = False
    #: judge every session as the revision's (E4); None: a session with ProgIdx or a result request is E4
    extension: bool | None = None
    #: T2 (robot): mean and per-second stream rate within this share of the declared rate
    rate_tolerance: float = 0.10
    #: T2 (robot): p99 |interval - period| within this share of the period
    jitter_tolerance: float = 0.50
    #: S5 (robot): seconds a connection may stay open after the session's command connection closed
    linger_s: float = 5.0
    #: judge the packets before the point where a capture file is cut short (else: exit 2)
    accept_truncated: bool = False

    def __post_init__(self) -> None:
        bad = [p for p in self.ports if not 0 < p <= 65535]
        if bad or not self.ports:
            raise ValueError(f"--port must be 1..65535, not {bad[0] if bad else 'nothing'}")
        check_tolerances(self.rate_tolerance, self.jitter_tolerance)
        if not 0 < self.linger_s <= 86_400:
            raise ValueError(f"--linger must be in (0, 86400] seconds, not {self.linger_s}")


@dataclass
class Stats:
    """Facts about the capture, for the report's header and the terminal."""

    frames: int = 0
    tcp_connections: int = 0
    udp_conversations: int = 0
    sessions: int = 0
    gaps: int = 0
    gap_bytes: int = 0
    cut_frames: int = 0  # iSight frames cut by a gap or the capture's end (not judged)
    skipped_bytes: int = 0  # bytes before the first plausible header of a direction (not judged)
    conflicts: int = 0  # retransmissions whose bytes differ from the original
    midstart: int = 0  # connections already open when the capture started
    open_at_end: int = 0  # connections still open when the capture ended
    robots: set[str] = field(default_factory=set)
    boxes: set[str] = field(default_factory=set)
    first_ts: float | None = None
    last_ts: float | None = None
    truncated: str | None = None
    skipped: dict[str, int] = field(default_factory=dict)  # frames not TCP/UDP, by reason


class Context:
    def __init__(self, config: AnalyzeConfig, source: Path | None = None) -> None:
        self.config = config
        self.source = source
        self.profile = config.profile
        #: frames are judged with tcp_check=zero: a TCP sender MUST send 00 00 (F6)
        self.judged = judge_profile(config.profile)
        self.time_out_s = config.profile.time_out_s
        self.vision_time_out_s = config.profile.vision_time_out_s
        self.findings = Findings()
        self.stats = Stats()
        self.latency = Series()  # every answered request but poses, ms
        #: (max latency, label, series) of the stream whose poses were answered slowest
        self.stream_plot: tuple[float, str, Series] | None = None
        self.intervals = Series()  # the robots' pose send intervals, ms
        self.cycles = Cycles()  # the boxes' cycle states, as the capture shows them
        self.now = 0.0  # time stamp of the packet being read
        self.frame = 0  # its frame number
        self._labels = 0

    def label(self) -> int:
        """The next connection number (1, 2, ... in the order connections appear in the capture)."""
        self._labels += 1
        return self._labels
