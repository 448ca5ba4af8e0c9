"""Runs fuzz cases against a box: one case, its probe, the oracle, and liveness (R2).

One case on TCP: the case's bytes (and the filler that completes a frame they leave
open) and a valid *probe* request in one write, on a connection that is reused from
case to case. Answers come in order (A1), so everything before the probe's answer is
the box's answer to the case, and the probe's answer bounds the wait without sleeping.
The probe, the sending and collecting, the settle window and the liveness check are the
harness's exchange engine (:mod:`conformance.harness.exchange`, :mod:`~conformance.harness.liveness`),
shared with the catalogue's malformed-input cases and ``replay``. A truncated
frame (``eof``) goes on a fresh connection that is then half-closed: no probe can
follow it. UDP: the datagram, then a probe datagram.

Liveness (R2) is checked on a fresh connection every ``liveness_every`` cases and
after every anomaly (the box closed or reset the connection, hung, sent a malformed
answer, or a case failed). So a box that dies, or only stops accepting connections
while the open one still works, is caught within ``liveness_every`` cases; the
campaign then finds which of those cases killed it (:mod:`.campaign`).

``isolate``: every case on a fresh connection; ``settle``: after the probe's answer
the connection is watched for ``settle_s`` for late extra answers (otherwise only what
has already arrived is taken, and ``settle_s`` after an answer with the probe's action
and an error, which may be a refusal of the bytes). The campaign
confirms a failure with both before it reports it, and shrinks isolated, so what a
box did with an earlier case on the same connection is never blamed on a later one.
"""

from __future__ import annotations

import socket
import time
from dataclasses import dataclass, field

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence, TcpConnection, UdpChannel
from ..harness.connection import Dialer
from ..harness.exchange import (
    PROBE_ACTIONS,
    Settle,
    action_of,
    answers_zero,
    choose_probe,
    probe_request,
    send_and_collect,
)
from ..harness.liveness import check_alive, responsive, unreachable_outcome
from ..harness.quiet import CUT_S
from ..harness.quiet import HANG_CASES as REFUSED_REPEAT
from ..harness.target import Target, Unreachable
from ..harness.transcript import Kind, Transcript
from ..model.verdicts import Verdict
from ..protocol import Action, Frame, Profile, Transport, codec_for
from ..protocol.framings import End
from . import second_look
from .oracle import Finding, Judgement, judge
from .strategies import FuzzCase

#: At most this many answers to one case are read (a box flooding answers ends the case).
MAX_ANSWERS = 64
#: R2: a fresh connection's NONE request got a frame-like answer (the harness's one liveness test).
alive = responsive

__all__ = ["MAX_ANSWERS", "PROBE_ACTIONS", "Executor", "Result", "Stats", "alive", "frame_of"]


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


#: per box (host, port): exchanges whose probe came back with an error and no 0000 within time_out
REFUSED_RUNS: dict[tuple[str, int], int] = {}


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
        #: the connections (the harness's: dial, send, receive with a deadline)
        self.dialer = Dialer(transcript, target, profile, time_out_s)
        self.time_out_s = self.dialer.time_out_s
        self.isolate = False
        self.settle = False
        self.stats = Stats()
        self.since_liveness = 0
        self.last_liveness: Outcome | None = None
        codec = codec_for(profile)
        self._probes: dict[Transport, dict[Action, bytes]] = {
            t: {a: codec.encode(probe_request(a, profile), t) for a in PROBE_ACTIONS} for t in (Transport.TCP, Transport.UDP)
        }
        self._conn: TcpConnection | None = None
        self._udp: UdpChannel | None = None

    # -- connections ---------------------------------------------------------------------
    def _connect(self, label: str) -> TcpConnection:
        conn = self.dialer.dial(label)
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
        self.last_liveness = check_alive(self.transcript, self.target, self.profile, time_out_s=self.time_out_s)
        return self.last_liveness

    # -- running -------------------------------------------------------------------------
    def probe_for(self, case: FuzzCase) -> Action | None:
        """An action neither the case's requests nor a frame some legal framing finds in its bytes has
        (else the first answer with it could be an embedded frame's, the probe's own answer arriving
        later, in the next case); None when all are taken: the case then goes without a probe."""
        return choose_probe(case.wire, case.actions)

    def _settle(self) -> Settle:
        """``settle``: the full window after the probe's answer; else only what has arrived (and the
        window after an answer with an error, which may be a refusal of the bytes)."""
        return Settle.fixed(self.settle_s) if self.settle else Settle(0.0, self.settle_s, 0.0)

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
                end = unreachable_outcome(exc, self.time_out_s)
                return Result(case, [], end, judge(case.expects, [], end, self.profile, Action.NONE), 0, True)
        conn = self._conn
        assert conn is not None
        sent_at = time.monotonic()
        result = self.exchange(conn, case, note)
        result.fresh = fresh
        if isinstance(result.end, Silence) and result.probe is not None:  # a stall, another framing, or a hang?
            where = second_look.Where(self.transcript, self.target, self.profile, self.time_out_s, self.stats.cases)
            second_look.recheck(where, conn, result, self._probes[Transport.TCP][result.probe], sent_at)
        if result.conn < 0:  # the box closed or hung: a new connection for the next case
            self._conn = None
            result.conn = conn.conn_id
            if isinstance(result.end, Silence):
                conn.abort("fuzz: the box hung; a new connection for the next case")
            else:
                conn.close("fuzz: the box closed the connection; a new one for the next case")
        return result

    def exchange(self, conn: TcpConnection, case: FuzzCase, note: str = "") -> Result:
        """The case's bytes and a probe on ``conn``; what came before the probe's answer, judged.

        ``result.conn`` is negative when the connection is no longer usable (closed, reset, hung)."""
        probe = self.probe_for(case)
        probe_bytes = self._probes[Transport.TCP][probe] if probe is not None else b""
        wire = case.wire + probe_bytes
        text = note or case.describe()
        text += f"; then a {probe.name} probe" if probe is not None else " (no probe: the bytes hold every probe action)"
        # bounded time: once the probe's action came back with an error and no 0000 behind it for the whole
        # time_out twice (a box whose answers after an error repeat it), that 0000 is awaited only CUT_S
        key = (self.target.host, self.target.port)  # per box, across the executors of one campaign's sessions
        cut = REFUSED_RUNS.get(key, 0) >= REFUSED_REPEAT
        got = send_and_collect(conn, case.wire, probe, probe_bytes, text, self._settle(), self.time_out_s,
                               splits=tuple(case.splits), gap_s=case.gap_s,
                               await_s=min(CUT_S, self.time_out_s) if cut else None)
        if got.ran_out and not cut:
            REFUSED_RUNS[key] = REFUSED_RUNS.get(key, 0) + 1
        outcomes, end = got.outcomes, got.end
        if got.probe_answered and got.kind is End.CLOSED:  # a refusal, then a close: the probe never read
            outcomes, end = [*outcomes, *got.answers()[-1:]], got.close
        judgement = judge(case.expects, outcomes, end, self.profile, probe, data=wire, extension=self.extension,
                          probe_at=len(case.wire) if probe is not None else None)
        return Result(case, outcomes, end, judgement, conn.conn_id if got.usable else -1, False, probe)

    def _run_eof(self, case: FuzzCase, note: str) -> Result:
        """A truncated frame: a fresh connection, the bytes, end of stream; what follows until the box closes."""
        self.stats.tcp += 1
        try:
            conn = self._connect("fuzz-eof")
        except Unreachable as exc:
            end: Outcome = unreachable_outcome(exc, self.time_out_s)
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
                self._udp = self.dialer.udp("fuzz-udp", self.udp_target)
            except Unreachable:
                gone = Closed(True, 0.0)
                return Result(case, [], gone, judge(case.expects, [], gone, self.profile, Action.NONE), 0, True)
        channel = self._udp
        probe = self.probe_for(case)
        start = time.monotonic()
        channel.send(case.wire, note or case.describe())
        if probe is not None:
            channel.send(self._probes[Transport.UDP][probe], f"a {probe.name} probe datagram")
        outcomes: list[Outcome] = []
        end: Outcome = Silence(0.0)
        while len(outcomes) < MAX_ANSWERS:
            outcome = channel.next_outcome(self.time_out_s, since=start)
            if (probe is not None and action_of(outcome) == probe) or isinstance(outcome, (Closed, Silence)):
                end = outcome
                break
            outcomes.append(outcome)
        if probe is not None and action_of(end) == probe and (self.settle or not answers_zero(end, probe)):
            extra = channel.next_outcome(self.settle_s)
            if answers_zero(extra, probe):
                outcomes.append(end)
                end = extra
        return Result(case, outcomes, end, judge(case.expects, outcomes, end, self.profile, probe,
                                                  transport=Transport.UDP), channel.conn_id, True, probe)


def frame_of(outcome: Outcome) -> Frame | None:
    return outcome.frame if isinstance(outcome, Answer) else None
