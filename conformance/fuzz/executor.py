"""Runs fuzz cases against a box: one case, its probe, the oracle, and liveness (R2).

One case on TCP: the case's bytes (and the filler that completes a frame they leave
open) and a valid *probe* request in one write, on a connection that is reused from
case to case. Answers come in order (A1), so everything before the probe's answer is
the box's answer to the case, and the probe's answer bounds the wait without sleeping.
The probe's action is one the case's bytes do not use, so the two cannot be confused;
if a probe-like answer is followed at once by another one, the first answered the case
(as :meth:`~conformance.suite.context.CaseContext.send_malformed` does). A truncated
frame (``eof``) goes on a fresh connection that is then half-closed: no probe can
follow it. UDP: the datagram, then a probe datagram.

Liveness (R2) is checked on a fresh connection every ``liveness_every`` cases and
after every anomaly (the box closed or reset the connection, hung, sent a malformed
answer, or a case failed). So a box that dies, or only stops accepting connections
while the open one still works, is caught within ``liveness_every`` cases; the
campaign then finds which of those cases killed it (:mod:`.campaign`).

``isolate``: every case on a fresh connection; ``settle``: after the probe's answer
the connection is watched for ``settle_s`` for late extra answers. The campaign
confirms a failure with both before it reports it, and shrinks isolated, so what a
box did with an earlier case on the same connection is never blamed on a later one.
"""

from __future__ import annotations

import socket
import time
from dataclasses import dataclass, field

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence, TcpConnection, UdpChannel
from ..harness.target import Target, Unreachable
from ..harness.transcript import Kind, Transcript
from ..protocol import Action, Frame, Profile, Transport, codec_for, request, tolerance_blocks
from ..protocol.framings import embedded_actions
from ..suite.context import probe_pose
from ..suite.verdicts import Verdict
from .oracle import Finding, Judgement, judge
from .strategies import FuzzCase

#: At most this many answers to one case are read (a box flooding answers ends the case).
MAX_ANSWERS = 64
#: Probes, in order of preference: each is answered 0000 in any cycle state.
PROBE_ACTIONS = (Action.NONE, Action.POSE, Action.TOLERANCE, Action.REGISTER_POSE)


class FuzzConnection(TcpConnection):
    """A recorded TCP connection that can also take what has already arrived, without waiting."""

    def poll(self) -> list[Outcome]:
        """Outcomes already received or decodable now (never waits)."""
        out: list[Outcome] = []
        if self.sock is not None and not self._closed and self.closed_by_peer is None:
            self._read(0.0, time.monotonic())
        while len(out) < MAX_ANSWERS:
            outcome = self.next_outcome(0.0)
            if isinstance(outcome, Silence):
                break
            out.append(outcome)
            if isinstance(outcome, Closed):
                break
        return out


@dataclass
class Result:
    """What one case did on the wire, and the oracle's judgement."""

    case: FuzzCase
    outcomes: list[Outcome]
    end: Outcome | None
    judgement: Judgement
    conn: int = 0  # connection id in the transcript
    fresh: bool = True  # the case was the first on its connection
    probe: Action | None = None
    liveness: Outcome | None = None  # set when a liveness check followed the case

    @property
    def verdict(self) -> Verdict:
        return self.judgement.verdict

    @property
    def anomaly(self) -> bool:
        """Anything that calls for a liveness check (and, on a reused connection, a new one)."""
        if self.verdict is Verdict.FAIL or any(isinstance(o, (Malformed, Closed)) for o in self.outcomes):
            return True
        if self.case.eof:  # a truncated frame ends with the box closing: that is the normal end
            return isinstance(self.end, Silence)
        return isinstance(self.end, (Closed, Silence))

    def observed(self) -> str:
        parts = [o.describe() for o in self.outcomes]
        if isinstance(self.end, Answer) and not parts:
            parts.append(f"stayed silent (it answered the probe behind the bytes: {self.end.frame.describe()})")
        elif isinstance(self.end, Answer):
            parts.append(f"then answered the probe ({self.end.frame.describe()})")
        elif self.end is not None:
            parts.append(self.end.describe())
        return "; ".join(parts) or "nothing"


@dataclass
class Stats:
    cases: int = 0
    tcp: int = 0
    udp: int = 0
    connections: int = 0
    liveness_checks: int = 0
    by_kind: dict[str, int] = field(default_factory=dict)


def alive(outcome: Outcome) -> bool:
    """R2: a fresh connection's NONE request got a frame-like answer."""
    if isinstance(outcome, Answer):
        return True
    return isinstance(outcome, Malformed) and outcome.error.header is not None


class Executor:
    """Sends fuzz cases to one box and judges what it does (see the module docstring)."""

    def __init__(
        self,
        target: Target,
        profile: Profile,
        transcript: Transcript,
        *,
        udp_target: Target | None = None,
        extension: bool = True,
        liveness_every: int = 64,
        settle_s: float = 0.05,
        time_out_s: float | None = None,
    ) -> None:
        self.target = target
        self.udp_target = udp_target
        self.profile = profile
        self.transcript = transcript
        self.extension = extension
        self.liveness_every = max(1, liveness_every)
        self.settle_s = settle_s
        self.time_out_s = time_out_s if time_out_s is not None else profile.time_out_ms / 1000
        self.isolate = False
        self.settle = False
        self.stats = Stats()
        self.since_liveness = 0
        self.last_liveness: Outcome | None = None
        codec = codec_for(profile)
        first = profile.first_index
        self._probes: dict[Transport, dict[Action, bytes]] = {
            t: {
                Action.NONE: codec.encode(request(Action.NONE), t),
                Action.POSE: codec.encode(probe_pose(profile), t),
                Action.TOLERANCE: codec.encode(request(Action.TOLERANCE, tolerance_blocks([0.5], first)), t),
                Action.REGISTER_POSE: codec.encode(request(Action.REGISTER_POSE, probe_pose(profile).blocks), t),
            }
            for t in (Transport.TCP, Transport.UDP)
        }
        self._conn: FuzzConnection | None = None
        self._udp: UdpChannel | None = None

    # -- connections ---------------------------------------------------------------------
    def _connect(self, label: str) -> FuzzConnection:
        conn = FuzzConnection(self.transcript, self.target, self.profile, label, self.time_out_s)
        conn.connect()
        self.stats.connections += 1
        return conn

    def drop_connection(self) -> None:
        """Close the reused connection (the next case opens a new one)."""
        if self._conn is not None:
            self._conn.close("fuzz: connection done")
            self._conn = None

    def close(self) -> None:
        self.drop_connection()
        if self._udp is not None:
            self._udp.close()
            self._udp = None

    def check_alive(self) -> Outcome:
        """R2: a NONE request on a fresh connection."""
        self.stats.liveness_checks += 1
        self.since_liveness = 0
        conn = TcpConnection(self.transcript, self.target, self.profile, "liveness", self.time_out_s)
        try:
            conn.connect()
        except Unreachable as exc:
            outcome: Outcome = Closed(True, 0.0) if "refused" in str(exc) else Silence(self.time_out_s)
        else:
            outcome = conn.request(self._probes[Transport.TCP][Action.NONE], "liveness check on a fresh connection (R2)")
            conn.close()
        self.last_liveness = outcome
        return outcome

    # -- running -------------------------------------------------------------------------
    def probe_for(self, case: FuzzCase) -> Action:
        """An action no frame in the case's bytes has under any legal framing (else the first answer with
        it could be an embedded frame's, the probe's own answer arriving later, in the next case)."""
        used = case.actions | embedded_actions(case.wire)
        return next((a for a in PROBE_ACTIONS if a not in used), Action.NONE)

    def run(self, case: FuzzCase, note: str = "") -> Result:
        """Send one case, judge it, and check liveness when it is due or something went wrong."""
        self.stats.cases += 1
        self.stats.by_kind[case.kind] = self.stats.by_kind.get(case.kind, 0) + 1
        if case.transport is Transport.UDP:
            result = self._run_udp(case, note)
        elif case.eof:
            result = self._run_eof(case, note)
        else:
            result = self._run_tcp(case, note)
        self.since_liveness += 1
        if result.anomaly or self.since_liveness >= self.liveness_every:
            result.liveness = self.check_alive()
        return result

    def _run_tcp(self, case: FuzzCase, note: str) -> Result:
        self.stats.tcp += 1
        fresh = self._conn is None or self.isolate
        if fresh:
            self.drop_connection()
            try:
                self._conn = self._connect("fuzz")
            except Unreachable as exc:
                end = Closed(True, 0.0) if "refused" in str(exc) else Silence(self.time_out_s)
                return Result(case, [], end, judge(case.expects, [], end, self.profile, Action.NONE), 0, True)
        conn = self._conn
        assert conn is not None
        result = self.exchange(conn, case, note)
        result.fresh = fresh
        if result.conn < 0:  # the box closed or hung: a new connection for the next case
            self._conn = None
            result.conn = conn.conn_id
            if isinstance(result.end, Silence):
                conn.abort("fuzz: the box hung; a new connection for the next case")
            else:
                conn.close("fuzz: the box closed the connection; a new one for the next case")
        return result

    def exchange(self, conn: FuzzConnection, case: FuzzCase, note: str = "") -> Result:
        """The case's bytes and a probe on ``conn``; what came before the probe's answer, judged.

        ``result.conn`` is negative when the connection is no longer usable (closed, reset, hung)."""
        probe = self.probe_for(case)
        start = time.monotonic()
        text = note or case.describe()
        if not conn.send(case.wire + self._probes[Transport.TCP][probe], f"{text}; then a {probe.name} probe"):
            outcomes: list[Outcome] = [o for o in conn.poll() if not isinstance(o, Closed)]
            end: Outcome = conn.closed_by_peer or Closed(False, 0.0)
            closed = True
        else:
            outcomes, end, closed = self._collect(conn, probe, start)
        usable = not (closed or isinstance(end, (Closed, Silence)))
        wire = case.wire + self._probes[Transport.TCP][probe]
        judgement = judge(case.expects, outcomes, end, self.profile, probe, data=wire, extension=self.extension,
                          probe_at=len(case.wire))
        return Result(case, outcomes, end, judgement, conn.conn_id if usable else -1, False, probe)

    def _collect(self, conn: FuzzConnection, probe: Action, start: float) -> tuple[list[Outcome], Outcome, bool]:
        """(answers to the case, how it ended: the probe's answer / Closed / Silence, the box closed after it)."""
        outcomes: list[Outcome] = []
        while len(outcomes) < MAX_ANSWERS:
            outcome = conn.next_outcome(self.time_out_s, since=start)
            if _probe_action(outcome, probe) and not _answers(outcome, probe):
                # the probe's action with an error: the probe's (wrong) answer, or an error answer to the case's
                # bytes with the probe's action (A5 allows that); a 0000 answer to the probe soon after tells
                extra = conn.drain(self.settle_s)
                close = next((o for o in extra if isinstance(o, Closed)), None)
                extra = [o for o in extra if not isinstance(o, Closed)]
                at = next((i for i, o in enumerate(extra) if _answers(o, probe)), None)
                if at is not None:  # the probe's 0000 came later: everything before it answered the case
                    outcomes += [outcome, *extra[:at]]
                    outcome, extra = extra[at], extra[at + 1 :]
                elif close is not None and not extra:  # then a close: the exchange ended with it, and the
                    return [*outcomes, outcome], close, True  # answer may be a refusal of the bytes (A5, R6 c)
                return outcomes + extra, outcome, close is not None
            if _answers(outcome, probe):
                extra = conn.drain(self.settle_s) if self.settle else conn.poll()
                closed = any(isinstance(o, Closed) for o in extra)
                extra = [o for o in extra if not isinstance(o, Closed)]
                if extra and _answers(extra[0], probe):  # the first probe-like answer answered the case
                    outcomes.append(outcome)
                    outcome = extra.pop(0)
                outcomes += extra  # late extras: the oracle sees them as unasked-for answers
                return outcomes, outcome, closed
            if isinstance(outcome, (Closed, Silence)):
                return outcomes, outcome, True
            outcomes.append(outcome)
        return outcomes, Silence(time.monotonic() - start), True

    def _run_eof(self, case: FuzzCase, note: str) -> Result:
        """A truncated frame: a fresh connection, the bytes, end of stream; what follows until the box closes."""
        self.stats.tcp += 1
        try:
            conn = self._connect("fuzz-eof")
        except Unreachable as exc:
            end: Outcome = Closed(True, 0.0) if "refused" in str(exc) else Silence(self.time_out_s)
            return Result(case, [], end, judge(case.expects, [], end, self.profile), 0, True)
        outcomes: list[Outcome] = []
        if conn.send(case.wire, note or case.describe()) and conn.sock is not None:
            try:
                conn.sock.shutdown(socket.SHUT_WR)
                self.transcript.add(conn.conn_id, Kind.CLOSE, note="end of stream after the truncated frame")
            except OSError:
                pass
        start = time.monotonic()
        end = conn.closed_by_peer or Silence(0.0)
        while len(outcomes) < MAX_ANSWERS and conn.closed_by_peer is None:
            outcome = conn.next_outcome(self.time_out_s, since=start)
            if isinstance(outcome, (Closed, Silence)):
                end = outcome
                break
            outcomes.append(outcome)
        conn.abort("fuzz: done")
        judgement = judge(case.expects, outcomes, end if isinstance(end, Closed) else None, self.profile,
                          data=case.wire, extension=self.extension, eof=True)
        if isinstance(end, Silence):
            judgement.findings.append(Finding(Verdict.NON_STRICT, "S5", "S5: after the robot ends the stream the box "
                                              "closes its side", f"{end.describe()} (the connection stayed open)"))
        return Result(case, outcomes, end, judgement, conn.conn_id, True)

    def _run_udp(self, case: FuzzCase, note: str) -> Result:
        self.stats.udp += 1
        if self.udp_target is None:
            raise RuntimeError("a UDP case without a UDP target")
        if self._udp is None:
            try:
                self._udp = UdpChannel(self.transcript, self.udp_target, self.profile, "fuzz-udp")
            except Unreachable:
                end: Outcome = Closed(True, 0.0)
                return Result(case, [], end, judge(case.expects, [], end, self.profile, Action.NONE), 0, True)
        channel = self._udp
        probe = self.probe_for(case)
        start = time.monotonic()
        channel.send(case.wire, note or case.describe())
        channel.send(self._probes[Transport.UDP][probe], f"a {probe.name} probe datagram")
        outcomes: list[Outcome] = []
        end = Silence(0.0)
        while len(outcomes) < MAX_ANSWERS:
            outcome = channel.next_outcome(self.time_out_s, since=start)
            if _probe_action(outcome, probe) or isinstance(outcome, (Closed, Silence)):
                end = outcome
                break
            outcomes.append(outcome)
        if _probe_action(end, probe) and (self.settle or not _answers(end, probe)):
            extra = channel.next_outcome(self.settle_s)
            if _answers(extra, probe):
                outcomes.append(end)
                end = extra
        return Result(case, outcomes, end, judge(case.expects, outcomes, end, self.profile, probe,
                                                  transport=Transport.UDP), channel.conn_id, True, probe)


def _answers(outcome: Outcome, probe: Action) -> bool:
    return isinstance(outcome, Answer) and outcome.frame.action == probe and outcome.frame.error_code == 0


def _probe_action(outcome: Outcome, probe: Action) -> bool:
    """An answer with the probe's action, even a malformed one: it ends the wait (the oracle attributes it)."""
    if isinstance(outcome, Answer):
        return outcome.frame.action == probe
    header = outcome.error.header if isinstance(outcome, Malformed) else None
    return header is not None and header.start_word == 0xFEFE and header.action == probe


def frame_of(outcome: Outcome) -> Frame | None:
    return outcome.frame if isinstance(outcome, Answer) else None
