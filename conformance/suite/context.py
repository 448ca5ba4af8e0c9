"""What one case works with: :class:`CaseContext`, the ``isight`` fixture.

It opens recorded connections and sends malformed input with a *probe* (a valid
request right behind it: answers come in order (A1), so the probe's answer bounds the
wait without sleeping). What the box did is attributed with every legal framing of
the bytes (:mod:`conformance.protocol.explain`): an answer belongs to the bytes some
legal framing makes it answer, so an answer to a valid frame embedded in bad bytes, or
the probe's own (even malformed) answer, is never taken for an answer to the bad bytes.
The session (:mod:`.session`) holds what lasts between cases: health, liveness (R2),
the witness, extension support.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from ..harness.client import MAX_DRAIN, Answer, Closed, Malformed, Outcome, Silence, TcpConnection, UdpChannel
from ..harness.target import Target, Unreachable
from ..harness.transcript import Transcript
from ..protocol import Action, Frame, Profile, encode, pose_blocks, request, tolerance_blocks
from ..protocol.answers import Seen
from ..protocol.explain import explain
from ..protocol.framings import End, Explanation, embedded_actions
from .judge import CaseVerdict, Inconclusive, Skip, broken, judge, judged_clauses, words
from .record import CaseRecord
from .session import UNREACHABLE_AT_CONNECT, SessionState
from .signature import Sig, Signature

PROBE_POSE_VALUES = (100.25, -200.5, 300.75, 0.0, 90.0, -180.0)
PROBE_NONE = request(Action.NONE)


def probe_pose(profile: Profile) -> Frame:
    """A valid pose request in this profile (its first index) used as a probe."""
    return request(Action.POSE, pose_blocks([PROBE_POSE_VALUES], profile.first_index))


def probe_for(bad: bytes, profile: Profile) -> Frame:
    """A valid request whose action no frame in ``bad`` has under any legal framing (R6: a
    receiver may resume at any start word), so the first answer with it is the probe's."""
    used = embedded_actions(bad)
    if Action.NONE not in used:
        return PROBE_NONE
    if Action.POSE not in used:
        return probe_pose(profile)
    return request(Action.TOLERANCE, tolerance_blocks([0.5], profile.first_index))


#: After the probe's answer, how long to keep reading for extras written with it (an answer nobody
#: asked for, A1; a close). Short: ~120 malformed-input cases each pay it on a conforming box.
AFTER_PROBE_S = 0.005

class CaseContext:
    """The ``isight`` fixture: everything one case needs, all of it recorded."""

    def __init__(self, session: SessionState, info: CaseRecord, transcript: Transcript,
                 params: dict[str, Any] | None = None) -> None:
        self.session = session
        self.info = info
        #: the case's parameters (pytest's callspec): requirement words and expectations may name them
        self.params: dict[str, Any] = dict(params or {})
        self.transcript = transcript
        self.settings = session.settings
        self.profile = session.profile
        self.time_out_s = self.settings.time_out_s
        self.needs_liveness = False
        self.informational: str | None = None
        self.latencies_ms: list[float] = []
        self.last_sent: bytes = b""
        self.last_probe: Outcome | None = None
        self.last_probe_action: Action = Action.NONE  # the action of the last probe (probe_for chose it)
        #: how the last malformed input was framed and judged (every legal framing considered)
        self.last_explanation: Explanation | None = None
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
        conn.before_send = self._not_known_late
        conn.on_answered = self.session.note_answered
        self._connections.append(conn)
        try:
            return conn.connect()
        except Unreachable as exc:
            raise Inconclusive(f"box unreachable: {exc}", signature=UNREACHABLE_AT_CONNECT) from None

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

        What the box sent back is attributed by every legal framing of ``bad`` plus the
        probe (:func:`conformance.protocol.explain.explain`): the answers that framing
        gives to ``bad``'s bytes (the first one is returned), or an answer no framing
        explains, or silence / the close. ``self.last_probe`` keeps what the box did with
        the probe (R6: did it resynchronise?). Any answer with the probe's action, even a
        malformed one, ends the wait. A liveness check on a fresh connection follows the
        case (R2)."""
        self.needs_liveness = True
        self.last_sent = bad
        if conn is None:
            conn = self.connect("malformed")
        probe = probe_for(bad, self.profile)
        self.last_probe_action = probe.action
        probe_bytes = encode(probe, self.profile)
        start = time.monotonic()
        if not conn.send(bad, note):
            self.last_probe = conn.closed_by_peer or Closed(False, 0.0)
            return self.last_probe
        conn.send(probe_bytes, f"probe: a valid {probe.action.name} request; its answer bounds the wait")
        outcomes, end = self._collect(conn, int(probe.action), start)
        answers = [o for o in outcomes if isinstance(o, (Answer, Malformed))]
        from ..fuzz.oracle import seen_of  # the outcome -> Seen adapter (no import circle: oracle needs no suite)

        seen: list[Seen] = [seen_of(o, self.profile) for o in answers]
        kind = End.CLOSED if isinstance(end, Closed) else End.SILENT if isinstance(end, Silence) else End.ANSWERED
        explanation = explain(bad + probe_bytes, seen, kind, self.profile,
                              extension=self.session.extension_supported is not False, probe_at=len(bad))
        self.last_explanation = explanation
        if explanation.framing != "reference":
            self.details["framing"] = explanation.framing
        mine = explanation.answers_within(0, len(bad))
        probe_event = explanation.event_at(len(bad))
        if probe_event is not None and probe_event.answer is not None:
            self.last_probe = answers[probe_event.answer]
        else:
            self.last_probe = end if end is not None else Silence(self.time_out_s)
        if mine:
            return answers[mine[0]]
        if explanation.unasked:
            return answers[explanation.unasked[0]]
        if isinstance(end, Closed) and not (probe_event is not None and probe_event.answer is not None):
            return end
        if isinstance(self.last_probe, (Answer, Malformed)):
            return Silence(self.last_probe.latency_s, skipped=True)
        return end if end is not None else Silence(self.time_out_s)

    def _collect(self, conn: TcpConnection, probe_action: int, start: float) -> tuple[list[Outcome], Outcome | None]:
        """What the box sent until an answer with the probe's action (then a short settle for
        late extras), a close or silence: (outcomes, how it ended; None: the probe's answer came)."""
        outcomes: list[Outcome] = []
        while len(outcomes) < MAX_DRAIN:
            outcome = conn.next_outcome(since=start)
            if isinstance(outcome, (Silence, Closed)):
                return outcomes, outcome
            outcomes.append(outcome)
            if _action_of(outcome) == probe_action:
                extra = conn.drain(AFTER_PROBE_S)
                closed = next((o for o in extra if isinstance(o, Closed)), None)
                return outcomes + [o for o in extra if not isinstance(o, Closed)], closed
        return outcomes, Silence(time.monotonic() - start)

    def _not_known_late(self, data: bytes) -> None:
        """Bounded time: a request the box is known not to answer within time_out ends the case at once."""
        if len(data) < 12 or data[:2] != b"\xfe\xfe" or not self.session.late:
            return
        try:
            name = Action(data[5]).name
        except ValueError:
            return
        cases = self.session.known_late(name)
        if cases is not None:
            raise Inconclusive(f"{name} is not answered within time_out (cases {', '.join(cases[:3])}): this case "
                               f"depends on it and is not run again", signature=Signature(Sig.SILENCE, name))

    def check_alive(self) -> Outcome:
        """R2: a fresh connection still gets NONE answered."""
        return self.session.probe(self.transcript)

    # -- verdict helpers ------------------------------------------------------------------
    def judge(self, outcome: Outcome, check: str = "", *, sent: bytes | None = None, **values: Any) -> None:
        """Judge ``outcome`` by the case record's requirement ``check`` (its words, its acceptable,
        SHOULD and unjudgeable outcomes, its level): return for PASS, raise the verdict otherwise.
        ``values`` (with the case's parameters) fill the requirement's words and expectations."""
        note = judge(outcome, self.info.check(check), self.info.level, {**self.params, **values},
                     sent=self.last_sent if sent is None else sent, profile=self.profile)
        if note:
            self.inform(note)

    def broken(self, check: str = "", *, expected: str, observed: str, sent: bytes = b"", received: bytes = b"",
               signature: Signature | None = None, **values: Any) -> CaseVerdict:
        """The verdict of a requirement the case judged by its own logic (raise it): the record
        gives the words and the level, the case what it expected and what it saw."""
        return broken(self.info.check(check), self.info.level, expected, observed, {**self.params, **values},
                      sent=sent, received=received, signature=signature)

    def judge_stream(self, result: Any, check: str = "stream", *, max_lost: int = 0, backlog: bool = False,
                     **values: Any) -> None:
        """Judge a pose stream (every pose answered 0000, none lost, no backlog) under the record's
        requirement ``check``: its words name each sub-requirement, its level sets the verdict."""
        from .pose_stream import judge_stream

        requirement = self.info.check(check)
        values = {**self.params, **values}
        judge_stream(result, requirement.level or self.info.level, words(requirement.text, values), max_lost=max_lost,
                     backlog=backlog, clauses=judged_clauses(requirement, values) or self.info.clauses)

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


def _action_of(outcome: Outcome) -> int | None:
    """The action byte of what the box sent: an answer, or malformed bytes with a readable header."""
    if isinstance(outcome, Answer):
        return int(outcome.frame.action)
    if isinstance(outcome, Malformed) and outcome.error.header is not None:
        return outcome.error.header.action
    return None
