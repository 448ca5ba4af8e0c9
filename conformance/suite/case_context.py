"""What one case works with: :class:`CaseContext`, the ``isight`` fixture.

It opens recorded connections and sends malformed input with a *probe* (a valid request right behind it,
whose answer bounds the wait, A1). What the box did is attributed with every legal framing of the bytes
(:mod:`conformance.protocol.explain`), so an answer to a valid frame embedded in bad bytes, or the probe's own,
is never taken for an answer to the bad bytes. The session (:mod:`conformance.runtime.run_state`) holds what
lasts between cases: health, liveness (R2), the witness, extension support.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence, TcpConnection, UdpChannel
from ..harness.exchange import (
    Collected,
    Settle,
    action_of,
    answers_zero,
    attribute,
    await_rest,
    choose_probe,
    collect,
    error_code,
    probe_request,
    send_and_collect,
)
from ..harness.liveness import LIVENESS_NOTE, PROBE_NONE, check_alive, cut_holds
from ..harness.quiet import (
    AFTER_FRAMES,
    CUT_S,
    HANG_CLAUSE,
    KIND_WORDS,
    REFUSED_KEYS,
    bad_kind,
    broken_besides_hang,
    hung,
    pattern_keys,
    probe_wronged,
    refused_key,
    whole_frames,
)
from ..harness.target import Target, Unreachable
from ..harness.transcript import Transcript
from ..harness.waits import COALESCED, SPLIT_PLACES, STREAM
from ..model.signature import Sig, Signature
from ..model.verdicts import Level, Verdict
from ..protocol import Action, Codec, Frame, codec_for, encode, peek_action, peek_header
from ..protocol.framings import Explanation
from ..runtime.run_state import UNREACHABLE_AT_CONNECT, SessionState
from .case_judge import CaseVerdict, Inconclusive, Skip, broken, judge, judged_clauses, words
from .record import CaseRecord

#: After the probe's answer, how long to keep reading for extras written with it (an answer nobody
#: asked for, A1; a close): the box's own pace, 5 to 50 ms (see harness.exchange.Settle).
SETTLE = Settle()


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
        #: the profile's codec: a case builds blocks by position with it (``isight.codec.pose_blocks(...)``),
        #: and it applies the profile's first index (B3)
        self.codec: Codec = codec_for(self.profile)
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
    def connect(self, label: str = "command", target: Target | None = None, time_out_s: float | None = None,
                prepare: Callable[[socket.socket], None] | None = None) -> TcpConnection:
        """A connected, recorded TCP connection (``prepare``: applied to the socket before it connects); an
        unreachable box ends the case INCONCLUSIVE."""
        conn = TcpConnection(self.transcript, target or self.target, self.profile, label, time_out_s)
        conn.before_connect = prepare
        conn.before_send = self._not_known_late
        self._bound_waits(conn)
        if self._waits_behind_another():
            conn.time_out_s = min(conn.time_out_s, CUT_S)
            conn.on_time_out = self._served_one_at_a_time
        self._connections.append(conn)
        try:
            return conn.connect()
        except Unreachable as exc:
            raise Inconclusive(f"box unreachable: {exc}", signature=UNREACHABLE_AT_CONNECT) from None

    def _bound_waits(self, conn: TcpConnection) -> None:
        """Bounded time (:mod:`.waits`): learn where requests go unanswered, and cut later waits there short."""
        ran_out = self.session.ran_out

        def answered(action: int) -> None:
            self.session.note_answered(action)
            ran_out.answered_at(conn.answers - 1)

        def cut(data: bytes, wait_s: float) -> None:
            place = COALESCED if not data else conn.answers
            cases = ran_out.known(place)
            if cases is None or not self._cut_holds(conn):
                return  # a dead box: the wait goes on, and R2 judges
            if place == COALESCED:
                nth = conn.answers - conn.answers_at_write + 1
                raise Inconclusive(
                    f"the box answered the first frame(s) of one write and left a later one unanswered for the whole "
                    f"time_out in cases {', '.join(cases[:3])} (R4, A1); here answer {nth} of {conn.write_frames} "
                    f"sent in one write did not come within {wait_s * 1000:.0f} ms either, so the wait ended there "
                    "(the box still answers a fresh connection)",
                    signature=Signature(Sig.SILENCE, "frames after the first of one write (R4)"), judged=("R4", "A1"))
            name = _action_name(data)
            raise Inconclusive(
                f"the box left the request after {place} answer(s) on a connection unanswered for the whole time_out "
                f"in cases {', '.join(cases[:3])} (A1, T1); here its {name} request was not answered within "
                f"{wait_s * 1000:.0f} ms either, so the wait ended there (the box still answers a fresh connection)",
                signature=Signature(Sig.SILENCE, name), judged=("A1", "T1"), sent=data)

        def coalesced(answered: bool) -> None:
            if answered:
                ran_out.answered_at(COALESCED)
            else:
                ran_out.ran_out(self.info.id, COALESCED)

        conn.on_answered = answered
        conn.wait_bound = lambda c: ran_out.bound(c.answers, self.time_out_s)
        conn.stream_bound = ran_out.bound(STREAM, self.time_out_s)
        conn.on_cut = cut
        conn.on_ran_out = lambda place: ran_out.ran_out(self.info.id, place)
        conn.coalesced_bound = ran_out.bound(COALESCED, self.time_out_s)
        conn.on_coalesced = coalesced
        self._bound_split_waits(conn)

    def _bound_split_waits(self, conn: TcpConnection) -> None:
        """Bounded time for bytes sent in pieces (:data:`~.waits.SPLIT`, R3): learnt as the other places."""
        ran_out = self.session.ran_out

        def split(answered: bool) -> None:
            place = SPLIT_PLACES[conn.split_write]
            if answered:
                ran_out.answered_at(place)
            else:
                ran_out.ran_out(self.info.id, place)

        def cut(wait_s: float) -> None:
            cases = ran_out.known(SPLIT_PLACES[conn.split_write])
            if cases is None or not self._cut_holds(conn):
                return  # a dead box: the wait goes on, and R2 judges
            raise Inconclusive(
                f"the box left bytes sent in pieces ({conn.split_write} split across segments) unanswered for the whole "
                f"time_out in cases {', '.join(cases[:3])} (R3: a frame split across segments is handled like the "
                f"whole); here too no answer came within {wait_s * 1000:.0f} ms of the last piece, so the wait "
                "ended there (the box still answers a fresh connection)",
                signature=Signature(Sig.SILENCE, "a frame sent in pieces (R3)"), judged=("R3", "A1"))

        conn.split_bound = lambda c: ran_out.bound(SPLIT_PLACES[c.split_write], self.time_out_s)
        conn.on_split = split
        conn.on_split_cut = cut

    def _waits_behind_another(self) -> bool:
        """The box serves one connection at a time (the S4 preflight) and this case holds one open: a
        new connection is not served until that one closes (unless the case judges S4 itself)."""
        judges = "S4" in self.info.clauses and self.info.level is not Level.MAY
        return (self.session.concurrent is False and not judges
                and any(isinstance(c, TcpConnection) and c.is_open for c in self._connections))

    def _served_one_at_a_time(self) -> None:
        raise Inconclusive(
            f"the box serves one connection at a time ({self.session.concurrency_note or 'the S4 preflight'}); this "
            f"case needs a second connection while its first is open, and it was not answered within "
            f"{CUT_S * 1000:.0f} ms: the case ends here, not judged", judged=("S4",))

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
        probe (:func:`conformance.harness.exchange.attribute`): the answers that framing
        gives to ``bad``'s bytes (the first one is returned), or an answer no framing
        explains, or silence / the close. ``self.last_probe`` keeps what the box did with
        the probe (R6: did it resynchronise?). Any answer with the probe's action, even a
        malformed one, ends the wait. A liveness check on a fresh connection follows the
        case (R2)."""
        self.needs_liveness = True
        self.last_sent = bad
        if conn is None:
            conn = self.connect("malformed")
        action = choose_probe(bad)
        self.last_probe_action = action if action is not None else Action.NONE
        probe_bytes = encode(probe_request(action, self.profile), self.profile) if action is not None else b""
        extension = self.session.extension_supported is not False
        kind = bad_kind(bad, self.profile, extension)
        text = f"{note}; then a valid {action.name} probe: its answer bounds the wait" if action is not None else note
        got = self._send_bounded(conn, bad, action, probe_bytes, text, kind)
        explanation = attribute(bad + probe_bytes, got, self.profile, extension=extension,
                                probe_at=len(bad) if action is not None else None)
        self.last_explanation = explanation
        if explanation.framing != "reference":
            self.details["framing"] = explanation.framing
        outcome = self._outcome_for_bad(bad, got, explanation)
        if action is not None:
            mine = bool(explanation.answers_within(0, len(bad)))
            if isinstance(self.last_probe, Answer):
                self.session.hangs.paced(self.last_probe.latency_s)
            for key in pattern_keys(kind, mine, whole_frames(bad, self.profile)):
                self.session.hangs.note(key, self.info.id, probe_answered=isinstance(
                    self.last_probe, (Answer, Malformed)), hung=isinstance(got.end, Silence) and hung(explanation))
            self._note_refused(kind, int(action), got, explanation)
        return outcome

    def _note_refused(self, kind: str, probe: int, got: Collected, explanation: Explanation) -> None:
        """The refused pattern (:func:`.quiet.refused_key`): noted when the wait for the probe's 0000 behind an
        error answer with its action ran out and nothing else is wrong; withdrawn when such a 0000 came."""
        code = error_code(got.end)
        if (got.ran_out and code and got.close is None and probe_wronged(explanation)
                and not broken_besides_hang(explanation, REFUSED_KEYS)):
            self.session.hangs.note(refused_key(kind), self.info.id, hung=True, probe_answered=False)
            if HANG_CLAUSE not in self.info.clauses:  # the R6 cases judge the probe's answer themselves
                name = action_name(probe)
                raise CaseVerdict(
                    Verdict.FAIL, f"A1: the valid {name} request behind the bytes was answered with error {code:04X}, "
                    f"and no 0000 followed within time_out ({self.time_out_s * 1000:.0f} ms)",
                    requirement="A1: the box answers every well-formed request (A4, S3: the probe is answered 0000)",
                    expected=f"the {name} request answered 0000 (after any refusal of the bytes)",
                    observed=got.end.describe() if got.end is not None else "", sent=self.last_sent,
                    received=got.end.raw if got.end is not None else b"", judged=("A1",),
                    signature=Signature(Sig.CODE, name, value=f"{code:04X}"))
        elif got.end is not None and answers_zero(got.end, probe) and any(
                action_of(o) == probe and error_code(o) for o in got.outcomes):
            self.session.hangs.withdraw_refused(kind)

    def _send_bounded(self, conn: TcpConnection, bad: bytes, action: Action | None, probe_bytes: bytes, text: str,
                      kind: str) -> Collected:
        """The exchange; on a box known to hang after this kind of bytes (:mod:`.quiet`), cut short."""
        judges = HANG_CLAUSE in self.info.clauses and self.info.level is not Level.MAY  # it reports the hang itself
        whole = whole_frames(bad, self.profile)
        bound = self.session.hangs.bound(kind, judges, self.time_out_s, whole) if action is not None else None
        got = send_and_collect(conn, bad, action, probe_bytes, text, SETTLE, bound)
        if bound is not None and action is not None and got.ran_out:
            return self._refused_bounded(conn, bad, action, probe_bytes, kind, bound, got)
        if bound is None or action is None or not isinstance(got.end, Silence):
            return got
        known = self.session.hangs.known_any(pattern_keys(kind, bool(got.answers()), whole))
        so_far = attribute(bad + probe_bytes, got, self.profile, extension=self.session.extension_supported is not False,
                           probe_at=len(bad))
        if known is not None and not broken_besides_hang(so_far):
            self._cut_short(conn, kind, bool(got.answers()), action, bound, known[1], known[0] == AFTER_FRAMES)
        # not in the pattern, or what came already breaks a requirement: wait out time_out, judged in full
        more = collect(conn, action, time.monotonic(), SETTLE, max(0.0, self.time_out_s - bound))
        return Collected(got.outcomes + more.outcomes, more.end, more.close)

    def _refused_bounded(self, conn: TcpConnection, bad: bytes, action: Action, probe_bytes: bytes, kind: str,
                         bound: float, got: Collected) -> Collected:
        """The probe's action came back with an error and no 0000 followed within ``bound``: INCONCLUSIVE under
        the refused pattern when it is established and nothing else is wrong; otherwise wait out time_out."""
        code = error_code(got.end)
        cases = self.session.hangs.known(refused_key(kind)) if code else None
        if cases is not None:
            so_far = attribute(bad + probe_bytes, got, self.profile,
                               extension=self.session.extension_supported is not False, probe_at=len(bad))
            if not broken_besides_hang(so_far, REFUSED_KEYS) and self._cut_holds(conn):
                what = KIND_WORDS.get(kind, kind)
                raise Inconclusive(
                    f"after {what} the box answered the request behind them ({action.name}) with error {code:04X} "
                    f"and no 0000 followed within the whole time_out in cases {', '.join(cases[:3])} (A1: a "
                    f"well-formed request is answered 0000); here too none came within {bound * 1000:.0f} ms, so the "
                    "wait ended there and what the box does with these bytes is not judged",
                    signature=Signature(Sig.CODE, action.name, value=f"{code:04X}"), judged=("A1",),
                    sent=self.last_sent)
        return await_rest(conn, int(action), got, max(0.0, self.time_out_s - bound))

    def _cut_holds(self, conn: TcpConnection) -> bool:
        """A short wait ran out: the box still answers a fresh connection (else R2 judges; its NONE's latency
        paces the short waits) and, one last look, nothing came on ``conn`` (else judged in full)."""
        return cut_holds(self.check_alive(), conn, self.session.hangs.paced)

    def _cut_short(self, conn: TcpConnection, kind: str, answered: bool, probe: Action, wait_s: float,
                   cases: list[str], after_frames: bool = False) -> None:
        """The probe behind bytes the box is known to hang on went unanswered for ``wait_s``: INCONCLUSIVE
        under that pattern (``after_frames``: :data:`~.quiet.AFTER_FRAMES`) if :meth:`_cut_holds`."""
        if not self._cut_holds(conn):
            return
        what = f"whole frames ({KIND_WORDS.get(kind, kind)}) in the same write as it" if after_frames else \
            KIND_WORDS.get(kind, kind) + (", once it answered them," if answered else "")
        clauses, why = (("R4", "A1"), "R4: every frame of a segment is answered") if answered or after_frames else (
            (HANG_CLAUSE,), "R6: hanging silently is NON-STRICT")
        raise Inconclusive(
            f"after {what} the box left the request behind them unanswered for the whole time_out in cases "
            f"{', '.join(cases[:3])} ({why}); here its probe ({probe.name}) was not answered within "
            f"{wait_s * 1000:.0f} ms either, so the wait ended there and what the box does with these bytes is not "
            "judged", signature=Signature(Sig.SILENCE, probe.name), judged=clauses, sent=self.last_sent)

    def _outcome_for_bad(self, bad: bytes, got: Collected, explanation: Explanation) -> Outcome:
        """What the box did with ``bad`` by the explanation (and, in ``last_probe``, with the probe)."""
        answers, end = got.answers(), got.close or got.end
        mine = explanation.answers_within(0, len(bad))
        probe_event = explanation.event_at(len(bad))
        probe_answered = probe_event is not None and probe_event.answer is not None
        if probe_answered:
            assert probe_event is not None and probe_event.answer is not None
            self.last_probe = answers[probe_event.answer]
        else:
            self.last_probe = end if isinstance(end, (Closed, Silence)) else Silence(self.time_out_s)
        if mine:
            return answers[mine[0]]
        if explanation.unasked:
            return answers[explanation.unasked[0]]
        if isinstance(end, Closed) and not probe_answered:
            return end
        if isinstance(self.last_probe, (Answer, Malformed)):
            return Silence(self.last_probe.latency_s, skipped=True)
        return end if isinstance(end, (Closed, Silence)) else Silence(self.time_out_s)

    def _not_known_late(self, data: bytes) -> None:
        """Bounded time: a request the box is known not to answer within time_out ends the case at once."""
        head = peek_header(data)
        if head is None or not head.start_ok or not self.session.late:
            return
        try:
            name = Action(head.action).name
        except ValueError:
            return
        cases = self.session.known_late(name)
        if cases is not None:
            raise Inconclusive(f"{name} is not answered within time_out (cases {', '.join(cases[:3])}): this case "
                               f"depends on it and is not run again", signature=Signature(Sig.SILENCE, name))

    def check_alive(self) -> Outcome:
        """R2: a fresh connection still gets NONE answered (on a box serving one connection at a time,
        while this case holds one open, a wait cut short: see :meth:`connect`)."""
        if not self._waits_behind_another():
            return check_alive(self.transcript, self.target, self.profile)
        conn = self.try_connect("liveness")
        if conn is None:
            return check_alive(self.transcript, self.target, self.profile)
        outcome = conn.request(PROBE_NONE, LIVENESS_NOTE)
        conn.close()
        return outcome

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


def _action_name(data: bytes) -> str:
    action = peek_action(data)
    return action_name(action) if action is not None else "unknown"


def action_name(action: int) -> str:
    try:
        return Action(action).name
    except ValueError:
        return f"0x{action:02X}"


def answers_none(outcome: Outcome) -> bool:
    return isinstance(outcome, Answer) and outcome.frame.action == Action.NONE and outcome.frame.error_code == 0

