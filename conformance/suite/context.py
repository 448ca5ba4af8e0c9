"""What a case works with: the session (target, health, extension) and its own context.

:class:`CaseContext` opens recorded connections, sends malformed input with a
*probe* (a valid request right behind it: answers come in order (A1), so the probe's
answer bounds the wait without sleeping), and checks liveness on a fresh connection
afterwards (R2). When the box dies, the session remembers it and later cases end
INCONCLUSIVE at once ("box unreachable") instead of waiting.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence, TcpConnection, UdpChannel
from ..harness.target import Target, Unreachable
from ..harness.transcript import Transcript
from ..protocol import Action, Frame, Profile, encode, pose_blocks, request
from .catalogue import CaseInfo
from .judge import Inconclusive, Skip
from .settings import SuiteSettings

#: How often a dead box is re-probed (seconds); in between, cases end INCONCLUSIVE at once.
DEAD_RECHECK_S = 5.0
PROBE_POSE_VALUES = (100.25, -200.5, 300.75, 0.0, 90.0, -180.0)
PROBE_NONE = request(Action.NONE)


def probe_pose(profile: Profile) -> Frame:
    """A valid pose request in this profile (its first index) used as a probe."""
    return request(Action.POSE, pose_blocks([PROBE_POSE_VALUES], profile.first_index))


@dataclass
class BoxHealth:
    dead_since_case: str | None = None
    reason: str = ""
    last_check: float = 0.0


@dataclass
class SessionState:
    """One per test session: settings, the resolved target, health, extension support."""

    settings: SuiteSettings
    health: BoxHealth = field(default_factory=BoxHealth)
    #: the first liveness check of the session: a box that never answered NONE in this
    #: profile cannot be said to have been *killed* by a case (R2)
    baseline: Outcome | None = None
    extension_supported: bool | None = None
    extension_how: str = ""
    embedded: Any = None  # BoxThread when the bundled box was started
    _target: Target | None = None
    _udp_target: Target | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    @property
    def profile(self) -> Profile:
        return self.settings.profile

    def target(self) -> Target:
        with self._lock:
            if self._target is None:
                self._target = self.settings.target or self._start_embedded()
            return self._target

    def udp_target(self) -> Target | None:
        self.target()
        return self.settings.udp_target or self._udp_target

    def stream_target(self) -> Target:
        return self.settings.stream_target or self.target()

    def target_label(self) -> str:
        if self.settings.target_label:
            return self.settings.target_label
        if self.settings.target is None and self._target is not None:
            return f"bundled reference box at {self._target}"
        return str(self.settings.target or "bundled reference box")

    def _start_embedded(self) -> Target:
        from ..endpoints.behaviour import BoxConfig
        from ..endpoints.box import BoxThread

        box = BoxThread(BoxConfig(profile=self.settings.profile), host="127.0.0.1", port=0).start()
        self.embedded = box
        if box.udp_port:
            self._udp_target = Target("127.0.0.1", box.udp_port)
        return Target("127.0.0.1", box.tcp_port)

    def stop(self) -> None:
        if self.embedded is not None:
            self.embedded.stop()
            self.embedded = None

    def detect_extension(self, transcript: Transcript) -> bool:
        """E: does the box implement 26/27? Decided once per session (or by --extension)."""
        if self.extension_supported is None:
            mode = self.settings.extension
            if mode != "auto":
                self.extension_supported = mode == "on"
                self.extension_how = "forced on" if mode == "on" else "off (--extension off)"
            else:
                conn = TcpConnection(transcript, self.target(), self.profile, "extension detection").connect()
                conn.send(request(Action.VISION_RESULT), "detect extension E: result request (27)")
                # a box without E may stay silent (A5): a NONE probe behind it bounds the wait
                conn.send(PROBE_NONE, "probe: NONE; its answer bounds the wait")
                outcome = conn.next_outcome()
                if isinstance(outcome, Answer) and answers_none(outcome):  # the probe answered first: 27 got none
                    outcome = Silence(outcome.latency_s)
                conn.close()
                # implemented = the box answers 27 at all, even wrongly (then the E cases judge it)
                header = outcome.error.header if isinstance(outcome, Malformed) else None
                self.extension_supported = (
                    isinstance(outcome, Answer) and outcome.frame.action == Action.VISION_RESULT
                ) or (header is not None and header.action == Action.VISION_RESULT and header.transfer_type == 0x10)
                self.extension_how = (
                    "detected (the box answered a result request)" if self.extension_supported
                    else f"not implemented (to a result request the box {outcome.describe()})"
                )
        return self.extension_supported


class CaseContext:
    """The ``isight`` fixture: everything one case needs, all of it recorded."""

    def __init__(self, session: SessionState, info: CaseInfo, transcript: Transcript) -> None:
        self.session = session
        self.info = info
        self.transcript = transcript
        self.settings = session.settings
        self.profile = session.profile
        self.time_out_s = self.settings.time_out_s
        self.needs_liveness = False
        self.informational: str | None = None
        self.latencies_ms: list[float] = []
        self.last_sent: bytes = b""
        self.last_probe: Outcome | None = None
        self.details: dict[str, Any] = {}
        self._connections: list[TcpConnection | UdpChannel] = []
        self.pcap: Path | None = None

    @property
    def target(self) -> Target:
        return self.session.target()

    # -- connections ---------------------------------------------------------------------
    def connect(self, label: str = "command", target: Target | None = None, time_out_s: float | None = None) -> TcpConnection:
        """A connected, recorded TCP connection; an unreachable box ends the case INCONCLUSIVE."""
        conn = TcpConnection(self.transcript, target or self.target, self.profile, label, time_out_s)
        self._connections.append(conn)
        try:
            return conn.connect()
        except Unreachable as exc:
            raise Inconclusive(f"box unreachable: {exc}") from None

    def try_connect(self, label: str = "command", time_out_s: float | None = None) -> TcpConnection | None:
        """Like :meth:`connect`, but None when the box cannot be reached (for R/S cases that judge it)."""
        try:
            return self.connect(label, time_out_s=time_out_s)
        except Inconclusive:
            return None

    def udp(self, label: str = "udp") -> UdpChannel:
        target = self.session.udp_target()
        if target is None:
            raise Skip("no --udp-target given: UDP cases are not run")
        channel = UdpChannel(self.transcript, target, self.profile, label)
        self._connections.append(channel)
        return channel

    def close_all(self) -> None:
        for conn in self._connections:
            try:
                conn.close()
            except OSError:
                pass
        self._connections.clear()

    # -- exchanges -----------------------------------------------------------------------
    def exchange(self, data: bytes | Frame, note: str = "", label: str = "command") -> Outcome:
        """On a fresh connection: send one request, return what followed, close."""
        conn = self.connect(label)
        raw = data if isinstance(data, bytes) else encode(data, self.profile)
        self.last_sent = raw
        outcome = conn.request(raw, note)
        self._record_latency(outcome)
        conn.close()
        return outcome

    def send_malformed(self, bad: bytes, note: str = "malformed input", conn: TcpConnection | None = None) -> Outcome:
        """Send ``bad`` followed by a valid probe request; return the box's outcome for ``bad``.

        The probe's answer (answers come in order, A1) shows that ``bad`` got no answer of
        its own, without waiting for time_out; ``self.last_probe`` keeps what the box did
        with the probe (R6: did it resynchronise?). A liveness check on a fresh
        connection follows the case (R2).
        """
        self.needs_liveness = True
        self.last_sent = bad
        if conn is None:
            conn = self.connect("malformed")
        probe = probe_pose(self.profile) if len(bad) > 5 and bad[5] == Action.NONE else PROBE_NONE
        probe_action = probe.action
        start = time.monotonic()
        if not conn.send(bad, note):
            self.last_probe = conn.closed_by_peer or Closed(False, 0.0)
            return self.last_probe
        conn.send(probe, f"probe: a valid {probe_action.name} request; its answer bounds the wait")
        first = conn.next_outcome(since=start)
        if _is_probe_answer(first, probe_action):
            # nothing came for ``bad`` before the probe's answer: silence, unless a second
            # probe-like answer trails (then the first one was the answer to ``bad``)
            extra = conn.drain(self.settings.settle_s)
            if extra and _is_probe_answer(extra[0], probe_action):
                self.last_probe = extra[0]
                return first
            self.last_probe = first
            return Silence(first.latency_s if isinstance(first, Answer) else 0.0)
        if isinstance(first, (Closed, Silence)):
            self.last_probe = first
            return first
        self.last_probe = conn.next_outcome()
        return first

    def check_alive(self) -> Outcome:
        """R2: a fresh connection still gets NONE answered."""
        conn = TcpConnection(self.transcript, self.target, self.profile, "liveness")
        try:
            conn.connect()
        except Unreachable as exc:
            return Closed(True, 0.0) if "refused" in str(exc) else Silence(self.time_out_s)
        outcome = conn.request(PROBE_NONE, "liveness check on a fresh connection (R2)")
        conn.close()
        return outcome

    # -- verdict helpers ------------------------------------------------------------------
    def inform(self, text: str) -> None:
        """Record behaviour that is reported, never judged (INFORMATIONAL)."""
        self.informational = text if self.informational is None else f"{self.informational}; {text}"

    def require_extension(self) -> None:
        if not self.session.detect_extension(self.transcript):
            raise Skip(f"extension E not implemented by the box: {self.session.extension_how}")

    def _record_latency(self, outcome: Outcome) -> None:
        if isinstance(outcome, Answer):
            self.latencies_ms.append(outcome.latency_s * 1000)


def answers_none(outcome: Outcome) -> bool:
    return isinstance(outcome, Answer) and outcome.frame.action == Action.NONE and outcome.frame.error_code == 0


def responsive(outcome: Outcome) -> bool:
    """R2/baseline: the box answered with something frame-like (whether right or not is
    for the cases to judge)."""
    if isinstance(outcome, Answer):
        return True
    return isinstance(outcome, Malformed) and outcome.error.header is not None


def _is_probe_answer(outcome: Outcome, action: Action) -> bool:
    return isinstance(outcome, Answer) and outcome.frame.action == action and outcome.frame.error_code == 0
