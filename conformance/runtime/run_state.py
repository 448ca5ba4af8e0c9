"""The run's state for one box (:class:`SessionState`): settings, the target, the box's health, and the rules between cases.

"Session" names three things in this house; here it is the first:

* **the run's state** (this module): one :class:`SessionState` per box under test, for a whole run;
* **an S1 session**: the protocol's canonical run order, configure → connect → poses on → CycleOn → … → disconnect (PROTOCOL.md S1);
* **pytest's session**: pytest's own object for one ``pytest`` invocation, which may hold several boxes' states.

The pytest plugin only forwards to :meth:`SessionState.before_case` and
:meth:`SessionState.after_case`:

* **Baseline** (once): does the box answer a NONE request at all, in this profile?
  A box that never does cannot be said to have been *killed* by a case (R2).
* **Preflight** (once, after a good baseline): does the box serve two connections at
  once (S4)? If it does, the suite keeps the first one open as a *witness*: when a
  fresh connection later goes unanswered, the witness tells a box that still works but
  accepts no new connections (S5: connections never freed) from a dead one (R2). A box
  that serves one connection at a time is recorded (a root cause, S4) and gets no
  witness (it would starve every case).
* **Before a case**: once the box is unreachable, cases end INCONCLUSIVE at once. The
  box is re-probed on a wall-clock schedule (at most every :data:`RECHECK_S` seconds),
  never once per case, so a dead box costs seconds, not minutes.
* **After a case** that sent malformed input or waited out a time_out: the case's
  connections are closed *first* (a box serving one connection at a time is then free),
  then a fresh connection must get NONE answered (R2).
"""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import pytest

from ..harness.client import Answer, Outcome, TcpConnection
from ..harness.extension_probe import Probe, ask_result, detect_with_probes
from ..harness.liveness import PROBE_NONE, check_alive, responsive
from ..harness.quiet import Hangs
from ..harness.target import Target, Unreachable
from ..harness.transcript import Kind, Transcript
from ..harness.waits import RanOut
from ..model.case_verdicts import CaseVerdict, Inconclusive
from ..model.signature import Death, DeathKind, Sig, Signature
from ..model.verdicts import Verdict
from ..protocol import Action, Profile
from . import box_stall
from .settings import SuiteSettings

#: How often an unreachable box is re-probed (seconds); in between, cases end INCONCLUSIVE at once.
RECHECK_S = 10.0
#: After this many cases found an action unanswered within time_out, later requests of it end their case
#: INCONCLUSIVE at once (explained by that root cause) instead of each waiting time_out again.
LATE_CASES = 2
#: the S4 preflight's pause between connection attempts while a one-at-a-time box frees its slot
REFUSED_RETRY_S = 0.05
R2_TEXT = "R2: whatever bytes one connection sends, the box keeps accepting and answering new connections"
#: the signature of a case that could not connect (context.connect): the session then looks for a death
UNREACHABLE_AT_CONNECT = Signature.unreachable("connect")
S5_TEXT = "S5: after the robot closes a connection the box frees it (it keeps accepting new connections)"


@dataclass
class Health:
    dead_since_case: str | None = None
    reason: str = ""
    next_check: float = 0.0  # monotonic time of the next re-probe


@dataclass
class SessionState:
    """One per test session: settings, the resolved target, health, extension support."""

    settings: SuiteSettings
    health: Health = field(default_factory=Health)
    #: the first liveness check of the session
    baseline: Outcome | None = None
    #: S4: True when the box answered a second connection while the first was open; None: not checked
    concurrent: bool | None = None
    concurrency_note: str = ""
    deaths: list[Death] = field(default_factory=list)
    extension_supported: bool | None = None
    extension_how: str = ""
    #: E3: the run's first result request (27), sent at session start before any case's cycle (None: not sent)
    first_result: Probe | None = None
    embedded: Any = None  # the bundled box, when the session started it
    opened: int = 0
    closed: int = 0
    writes: int = 0  # writes made to the box by the cases so far (a box stall names the one it began after)
    #: action name -> ids of the cases that found it unanswered within time_out
    late: dict[str, list[str]] = field(default_factory=dict)
    #: actions the box has answered within the wait at least once this session
    answered: set[str] = field(default_factory=set)
    #: the patterns of bad bytes after which the box leaves the probe unanswered (bounded time: :mod:`.quiet`)
    hangs: Hangs = field(default_factory=Hangs)
    #: the places on a connection where the box leaves well-formed requests unanswered (:mod:`.waits`)
    ran_out: RanOut = field(default_factory=RanOut)
    _target: Target | None = None
    _udp_target: Target | None = None
    _witness: TcpConnection | None = None
    _log: Transcript = field(default_factory=lambda: Transcript(case_id="session"))
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _boxes: contextlib.ExitStack = field(default_factory=contextlib.ExitStack)

    @property
    def profile(self) -> Profile:
        return self.settings.profile

    @property
    def time_out_s(self) -> float:
        return self.settings.time_out_s

    # -- the target -----------------------------------------------------------------------
    def target(self) -> Target:
        with self._lock:
            if self._target is None:
                from ..endpoints.bundled import bundled_or_target

                self._target, self._udp_target, self.embedded = self._boxes.enter_context(
                    bundled_or_target(self.settings.target, None, self.profile))
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

    def stop(self) -> None:
        if self._witness is not None:
            self._witness.close("end of the session")
            self._witness = None
        self._boxes.close()  # the bundled box, if the session started it
        self.embedded = None

    # -- probes ---------------------------------------------------------------------------
    def probe(self, transcript: Transcript, label: str = "liveness") -> Outcome:
        """R2: a NONE request on a fresh connection (what the box did, never an exception)."""
        return check_alive(transcript, self.target(), self.profile, label=label)

    def baseline_ok(self) -> bool:
        return self.baseline is not None and responsive(self.baseline)

    # -- before a case --------------------------------------------------------------------
    def before_case(self, case_id: str, transcript: Transcript, any_profile: bool = False) -> None:
        """Baseline and preflight once; then refuse the case at once if the box is unreachable."""
        if self.baseline is None:
            self._baseline(transcript)
        if not any_profile:
            self._refuse_if_unreachable(transcript)

    def _baseline(self, transcript: Transcript) -> None:
        try:
            self.target()
        except Exception as exc:  # the bundled box failed to start: the suite's fault
            raise RuntimeError(f"could not start the bundled reference box: {exc}") from exc
        self.baseline = self.probe(transcript)
        if isinstance(self.baseline, Answer):
            self.answered.add(Action.NONE.name)
        if not responsive(self.baseline):
            self._mark_dead("session start", f"the box does not answer a NONE request (it {self.baseline.describe()}); "
                            "PROFILE-01 tells which profile it appears to use")
            self.deaths.append(Death("session start", DeathKind.UNRESPONSIVE, self.baseline.describe(), self.opened,
                                     self.closed))
            return
        self._preflight(transcript)
        self._first_result(transcript)

    def _first_result(self, transcript: Transcript) -> None:
        """E3 on a box that has run no cycle for this suite yet: the run's first result request (27) goes out at
        session start (with ``--extension auto`` it is the detection's), its outcome kept for E3-02."""
        if self.settings.extension == "off":
            return
        conn = TcpConnection(transcript, self.target(), self.profile, "session start: the first result request (E3)")
        try:
            conn.connect()
        except Unreachable:
            return  # the cases' liveness checks report it
        try:
            if self.settings.extension == "auto" and self.extension_supported is None:
                self.extension_supported, self.extension_how, seen = detect_with_probes(conn)
                self.first_result = seen[0]
            else:
                self.first_result = ask_result(conn, "session start: the first result request (27), before any cycle")
        finally:
            conn.close()

    def _preflight(self, transcript: Transcript) -> None:
        """S4: a second connection while the first is open; the first stays open as the witness."""
        first = self._connect_once_freed(transcript, "preflight: first connection")  # the baseline's just closed
        if first is None:
            return
        if not isinstance(first.request(PROBE_NONE, "preflight: NONE on the first connection"), Answer):
            first.close()
            return
        second = TcpConnection(transcript, self.target(), self.profile, "preflight: second connection, first open")
        try:
            second.connect()
        except Unreachable as exc:  # e.g. an embedded stack with room for one connection
            first.close("preflight: the first connection closes; is a new one accepted now?")
            self._one_at_a_time_refused(transcript, str(exc))
            return
        outcome = second.request(PROBE_NONE, "preflight: NONE on a second connection while the first is open (S4)")
        if responsive(outcome):
            self.concurrent = True
            second.close()
            first.transcript = self._log  # the witness outlives this case's transcript
            self._witness = first
            return
        first.close("preflight: the first connection closes; does the second get its answer now?")
        later = second.next_outcome()
        second.close()
        self.concurrent = False
        self.concurrency_note = (
            f"while a first connection was open, a second connection's NONE request {outcome.describe()}; "
            + (f"once the first closed, it was answered ({later.describe()})" if responsive(later)
               else f"after the first closed it {later.describe()}"))

    def _connect_once_freed(self, transcript: Transcript, why: str) -> TcpConnection | None:
        """A connection made right after one closed: a box with room for one connection frees its slot once it
        has seen the close, so a refusal is retried for up to time_out (None: refused all along)."""
        deadline = time.monotonic() + self.profile.time_out_s
        while True:
            conn = TcpConnection(transcript, self.target(), self.profile, why)
            try:
                conn.connect()
                return conn
            except Unreachable:
                conn.close()
                if time.monotonic() >= deadline:
                    return None
                time.sleep(REFUSED_RETRY_S)

    def _one_at_a_time_refused(self, transcript: Transcript, refusal: str) -> None:
        """S4: the second connection was refused while the first was open; one after it closes?"""
        third = self._connect_once_freed(transcript, "preflight: a new connection, first closed")
        if third is None:
            return  # refused alike with nothing open: not a concurrency fact (the cases will tell)
        outcome = third.request(PROBE_NONE, "preflight: NONE on a new connection once the first closed")
        third.close()
        if responsive(outcome):
            self.concurrent = False
            self.concurrency_note = (f"while a first connection was open, a second connection was refused ({refusal}); "
                                     f"once the first closed, a new connection was answered ({outcome.describe()})")

    def _refuse_if_unreachable(self, transcript: Transcript) -> None:
        health = self.health
        if health.dead_since_case is None:
            return
        if time.monotonic() >= health.next_check:
            outcome = self.probe(transcript, "re-probe")
            health.next_check = time.monotonic() + RECHECK_S
            if responsive(outcome):
                health.dead_since_case = None
                transcript.note("the box answers again")
                return
        raise Inconclusive(f"box unreachable since case {health.dead_since_case} ({health.reason})",
                           signature=Signature.unreachable(health.dead_since_case))

    def known_late(self, action: str) -> list[str] | None:
        """The cases that established that ``action`` is not answered within time_out (None: not
        established, or the box has answered it in time at least once: then the silences had another cause)."""
        cases = self.late.get(action, [])
        return cases if len(cases) >= LATE_CASES and action not in self.answered else None

    def note_answered(self, action: int) -> None:
        try:
            self.answered.add(Action(action).name)
        except ValueError:
            pass

    def _mark_dead(self, case_id: str, reason: str) -> None:
        self.health.dead_since_case = case_id
        self.health.reason = reason
        self.health.next_check = time.monotonic() + RECHECK_S

    # -- after a case ---------------------------------------------------------------------
    def after_case(self, case_id: str, transcript: Transcript, *, malformed_input: bool, last_sent: bytes,
                   error: BaseException | None) -> BaseException | None:
        """R2 after malformed input or a time_out (the case's connections already closed):
        returns the error the case ends with (the case's own, or an R2/S5 verdict)."""
        signature = error.signature if isinstance(error, CaseVerdict) and error.verdict is Verdict.FAIL else None
        if signature is not None and signature.kind is Sig.SILENCE:
            self.late.setdefault(signature.subject, []).append(case_id)
        self.ran_out.case_ended(case_id, signature is not None and signature.kind is Sig.SILENCE,
                                isinstance(error, CaseVerdict) and error.verdict is Verdict.FAIL)
        refused = isinstance(error, Inconclusive) and error.signature == UNREACHABLE_AT_CONNECT
        if (not (malformed_input or transcript.timeouts or refused) or (isinstance(error, Inconclusive) and not refused)
                or self.health.dead_since_case is not None):  # already known unreachable: nothing to learn
            self._count(transcript)
            return error
        ended = time.time()
        alive = self.probe(transcript)
        self._count(transcript)
        usual = self.baseline.latency_s if isinstance(self.baseline, Answer) else 0.0
        late = box_stall.held(transcript, alive, usual, self.profile.time_out_s, case_id, last_sent, self.writes,
                              ended)
        if late is not None:  # the fresh connection was held too: a stall of the whole box, not this case's input
            return box_stall.verdict(late, last_sent)
        if responsive(alive):
            return error
        stall = box_stall.look_again(transcript, self.target(), self.profile, case_id, last_sent, self.writes, ended)
        if stall is not None:  # the box came back: it stalled as a whole (T1, S4), the case's input not blamed
            return box_stall.verdict(stall, last_sent)
        kind, detail = self._diagnose(alive, transcript)
        self.deaths.append(Death(case_id, kind, detail, self.opened, self.closed))
        self._mark_dead(case_id, f"a fresh connection {alive.describe()}")
        if not (malformed_input and self.baseline_ok()) or refused:  # the death explains this case; no verdict of its own
            return error
        if kind is DeathKind.CONNECTION_LEAK:
            verdict = CaseVerdict(
                Verdict.FAIL, f"S5: the box stopped accepting new connections after the suite had opened {self.opened} "
                f"and closed {self.closed} ({detail})", requirement=S5_TEXT,
                expected="a fresh connection's NONE request answered", observed=detail, sent=last_sent,
                judged=("S5",), signature=Signature(Sig.NOT_ACCEPTING))
        else:
            verdict = CaseVerdict(
                Verdict.FAIL, f"R2: after this case's input the box no longer answers a fresh connection ({detail})",
                requirement=R2_TEXT, expected="a fresh connection's NONE request answered", observed=detail,
                sent=last_sent, judged=("R2",), signature=Signature(Sig.DEAD, case_id))
        if isinstance(error, CaseVerdict) and error.verdict is Verdict.FAIL:
            error.message += f" (and then {verdict.message})"
            error.judged = tuple(dict.fromkeys((*error.judged, *verdict.judged)))
            return error
        return verdict

    def _diagnose(self, alive: Outcome, transcript: Transcript) -> tuple[DeathKind, str]:
        """Dead (R2), or alive on the witness but not accepting new connections (S5)?"""
        witness = self._witness
        fresh = f"a fresh connection {alive.describe()}"
        if witness is None or witness.closed_by_peer is not None:
            return DeathKind.DEAD_AFTER_INPUT, fresh
        outcome = witness.request(PROBE_NONE, "witness: is the box alive on a connection it accepted earlier?")
        if responsive(outcome):
            return DeathKind.CONNECTION_LEAK, (f"{fresh}, yet it answers on a connection it accepted earlier: it accepts no new "
                                     f"connections after the suite opened {self.opened} and closed {self.closed}")
        self._witness = None
        witness.abort("witness gone")
        return DeathKind.DEAD_AFTER_INPUT, f"{fresh}, and a connection it accepted earlier {outcome.describe()} too"

    def _count(self, transcript: Transcript) -> None:
        tcp = {c for c, info in transcript.connections.items() if info.transport == "tcp"}
        failed = {e.conn for e in transcript.events if e.kind == Kind.CONNECT_FAILED}
        ends = {e.conn for e in transcript.events if e.kind in (Kind.CLOSE, Kind.ABORT)}
        self.opened += len(tcp - failed)
        self.closed += len((tcp - failed) & ends)
        self.writes += sum(1 for e in transcript.events if e.kind == Kind.SEND)

    # -- extension E ----------------------------------------------------------------------
    def detect_extension(self, transcript: Transcript) -> bool:
        """E: does the box implement 26/27? Decided once per session (or by --extension)."""
        if self.extension_supported is None:
            mode = self.settings.extension
            if mode != "auto":
                self.extension_supported = mode == "on"
                self.extension_how = "forced on" if mode == "on" else "off (--extension off)"
            else:
                conn = TcpConnection(transcript, self.target(), self.profile, "extension detection")
                try:
                    conn.connect()
                except Unreachable as exc:
                    raise Inconclusive(f"box unreachable: {exc}") from None
                self.extension_supported, self.extension_how, seen = detect_with_probes(conn)
                self.first_result = self.first_result or seen[0]
                conn.close()
        return self.extension_supported


#: the first box's session (the settings every session shares), in the pytest config's stash
STATE = pytest.StashKey["SessionState"]()
