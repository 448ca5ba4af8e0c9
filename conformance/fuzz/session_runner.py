"""Stateful fuzzing: sessions of the state machine (:mod:`.session_machine`), run in slices between the frame cases.

A :class:`SessionRunner` runs *chunks*: a *steered* session that walks straight to the
transitions of :class:`~.state_coverage.StateCoverage` no session has reached yet (at most
``STEER_PER_CHUNK``, each tried at most twice: the box may refuse the way there; the
first one also opens 16 connections at once and makes 32 quick reconnects), then one
hypothesis run of ``RUNS_PER_CHUNK`` sessions of ``STEPS`` steps each (seeded from the
campaign's seed, the campaign's database). The
campaign interleaves the chunks with its frame cases from the first second, so a
defect behind a request sequence is found as early as one behind a single frame.

A failure is shrunk by hypothesis to the shortest session that still fails (a steered
one is already a few requests long) and written as a vector file (the request that
failed), an ``isight-sequence-1`` file replaying the whole session (``isight-conformance
run --sequence FILE``) and a pcap. Its finding is then *known*: a later session that
meets it again stops without reporting it twice. After a failure the box is checked on
a fresh connection; a dead box is brought back (``recover``) or the runner stops.

:func:`run_stateful` runs chunks while a step budget allows (the campaign uses the
runner directly).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from hypothesis import HealthCheck, Phase, Verbosity, settings
from hypothesis.errors import Flaky
from hypothesis.stateful import run_state_machine_as_test

from ..harness.transcript import Transcript
from .config import CampaignConfig
from .death_first import DEATH_KEY
from .executor import Executor, alive
from .failure_files import Failure, clauses_of, write_pcap, write_sequence, write_vectors
from .hyp import seed_machine
from .last_words import LastWords, telling
from .session_machine import KnownFailure, SessionContext, StatefulFailure, StatefulHang, machine_for
from .state_coverage import StateCoverage, Transition
from .strategies import Strategies
from .transcript_replay import replay_sends

#: Steps per session (hypothesis's stateful_step_count) and sessions per hypothesis run.
STEPS = 25
RUNS_PER_CHUNK = 5
#: Unreached transitions a steered session walks to per chunk, and how often each is tried.
STEER_PER_CHUNK = 32
STEER_TRIES = 2


_UNSHRUNK = {False: "not shrunk: the box hung, each shrink step would wait time_out",
             True: "not shrunk: the box died, each shrink step would need a restart"}


@dataclass
class StatefulResult:
    """What the session runs did: the campaign adds the counts and the failures to its own."""

    runs: int = 0
    steps: int = 0
    failures: list[Failure] = field(default_factory=list)
    stopped: str = ""  # why the runs ended before the budget did: "failure", "hang", "flaky", "dead" ("": budget)


class SessionRunner:
    """Session chunks for one campaign (see the module docstring).

    ``budget()``: may another step run; ``number()``: the next failure's number;
    ``recover()``: bring a dead box back (False: it did not come back)."""

    def __init__(self, cfg: CampaignConfig, strategies: Strategies, campaign_seed: int, budget: Callable[[], bool],
                 number: Callable[[], int], recover: Callable[[], bool] | None = None) -> None:
        self.cfg = cfg
        self.seed = campaign_seed
        self.ctx = SessionContext(cfg, strategies, budget, StateCoverage(cfg.extension, campaign_seed))
        self.machine = machine_for(self.ctx)
        self.number = number
        self.recover = recover
        self.chunk = 0
        self.failures: list[Failure] = []
        self.stopped = ""
        self.tries: dict[Transition, int] = {}

    @property
    def coverage(self) -> StateCoverage:
        return self.ctx.coverage

    @property
    def result(self) -> StatefulResult:
        return StatefulResult(self.ctx.runs, self.ctx.steps, self.failures, self.stopped)

    def run_chunk(self) -> list[Failure]:
        """A steered session, then one hypothesis run of sessions; the failures found (recorded)."""
        before = len(self.failures)
        self._steer()
        if len(self.failures) == before and not self.stopped:
            self._hypothesis_chunk()
        self.chunk += 1
        return self.failures[before:]

    def _hypothesis_chunk(self) -> bool:
        """True when it ended on a failure (or the runner stopped)."""
        cfg, ctx = self.cfg, self.ctx
        seed_machine(self.machine, self.seed * 7919 + self.chunk)
        hyp = settings(
            max_examples=RUNS_PER_CHUNK, stateful_step_count=STEPS, deadline=None, database=cfg.database,
            phases=[Phase.generate, Phase.shrink] if self.chunk else [Phase.reuse, Phase.generate, Phase.shrink],
            suppress_health_check=list(HealthCheck), report_multiple_bugs=False, derandomize=False,
            verbosity=Verbosity.quiet, print_blob=False,
        )
        ctx.shrinking = False
        try:
            run_state_machine_as_test(self.machine, settings=hyp)
        except StatefulFailure as exc:
            self._found(exc, shrunk=True)
        except StatefulHang as exc:  # not shrunk: each step would wait time_out, or need a restart
            self._found(exc.failure, shrunk=False, how=_UNSHRUNK[exc.dead], stopped="hang")
        except KnownFailure:
            self._after_failure()
        except Flaky as exc:
            cfg.log(f"fuzz: a session failure did not reproduce when hypothesis replayed it ({type(exc).__name__})")
            self._after_failure()
        else:
            return False
        finally:
            ctx.shrinking = False
        return True

    def _steer(self) -> None:
        targets = [t for t in self.coverage.unreached() if self.tries.get(t, 0) < STEER_TRIES][:STEER_PER_CHUNK]
        if not targets or not self.ctx.left():
            return
        if not self.tries:  # the connection patterns at their largest, once, in a session of their own
            self._walk(None)
        for i in range(0, len(targets), 8):  # sessions of eight walks
            if not self.ctx.left() or self.stopped:
                break
            batch = targets[i : i + 8]
            for target in batch:
                self.tries[target] = self.tries.get(target, 0) + 1
            self._walk(batch)

    def _walk(self, targets: list[Transition] | None) -> None:
        """One steered session: to each target in turn (None: the connection patterns); a failure is walked
        to again on its own, in a fresh session, and the shorter session that fails is reported."""
        done: Transition | None = None
        try:
            found = self._session(targets)
            if found is None:
                return
            exc, done = found
            if done is not None and not isinstance(exc, StatefulHang):
                alone = self._session([done])
                if alone is not None and type(alone[0]) is type(exc):
                    exc = alone[0]
            if isinstance(exc, StatefulHang):
                self._found(exc.failure, False, "found by steering; " + _UNSHRUNK[exc.dead], "hang")
            elif isinstance(exc, StatefulFailure):
                self._found(exc, False, "found by steering toward an unreached state transition, walked to alone")
            else:
                self._after_failure()
        finally:
            self.ctx.shrinking = False

    def _session(self, targets: list[Transition] | None) -> tuple[BaseException, Transition | None] | None:
        """Walk to ``targets`` in a fresh session; the failure and the target it happened on, else None."""
        session = None
        current: Transition | None = None
        try:
            session = self.machine()
            if targets is None:
                session.connection_patterns()
            for current in targets or []:
                session.steer(current)
            session.teardown()
            return None
        except (StatefulFailure, StatefulHang, KnownFailure) as exc:
            return exc, current
        finally:
            self.ctx.shrinking = False
            if session is not None:
                for conn in session.conns.values():
                    conn.abort("steered session done")

    def _found(self, exc: StatefulFailure, shrunk: bool, how: str = "", stopped: str = "failure") -> None:
        confirmed, words = True, None
        if exc.finding.key.startswith(DEATH_KEY):
            box = self.cfg.box
            first = len(box.incarnations) if box is not None else 0
            said = [box.last_words()] if box is not None else []
            confirmed, why = self._confirm_death(exc)
            how = f"{how}; {why}" if how else why
            words = telling(said + ([i.last_words(0.0) for i in box.incarnations[first:-1]] if box else []))
        failure = _record(self.cfg, self.seed, self.number(), exc, shrunk, how, words)
        failure.confirmed = confirmed
        self.failures.append(failure)
        if exc.finding.key:
            self.ctx.known.add(exc.finding.key)
        self.stopped = stopped
        self._after_failure()

    def _confirm_death(self, exc: StatefulFailure) -> tuple[bool, str]:
        """R2 confirmed by the restart replay: bring the box back, replay the session's writes, is it dead again?"""
        if self.recover is None:
            return False, "not confirmed: the campaign cannot restart the box (fuzz --restart-cmd CMD)"
        if not self.recover():
            return False, "not confirmed: the box did not come back"
        cfg = self.cfg
        tr = Transcript(case_id="FUZZ-stateful-death")
        replay_sends(exc.transcript, cfg.profile, tr)
        if alive(Executor(cfg.target, cfg.profile, tr, extension=cfg.extension).check_alive()):
            return False, "not confirmed: replayed after a restart, the session's writes did not kill the box again"
        exc.transcript = tr  # the evidence: the replay that killed it again
        return True, "confirmed: after a restart, the session's writes replayed on fresh connections killed it again"

    def _after_failure(self) -> None:
        """After a failing session: is the box still there? A dead one is brought back, or the runner stops."""
        cfg = self.cfg
        ex = Executor(cfg.target, cfg.profile, Transcript(case_id="FUZZ-stateful-liveness"), extension=cfg.extension)
        if alive(ex.check_alive()):
            return
        if self.recover is None or not self.recover():
            self.stopped = "dead"


def run_stateful(cfg: CampaignConfig, strategies: Strategies, campaign_seed: int, budget: Callable[[int], bool],
                 number: int) -> StatefulResult:
    """Session chunks while ``budget(steps)`` allows, until the first failure (written as failure ``number``)."""
    runner: SessionRunner

    def left() -> bool:
        return budget(runner.ctx.steps)

    runner = SessionRunner(cfg, strategies, campaign_seed, left, lambda: number + len(runner.failures))
    while left() and not runner.failures and not runner.stopped:
        runner.run_chunk()
    return runner.result


def _record(cfg: CampaignConfig, campaign_seed: int, number: int, exc: StatefulFailure, shrunk: bool = True,
            how: str = "", words: LastWords | None = None) -> Failure:
    """The session failure's vector file (the failing request), sequence file and pcap, and a line in the log."""
    name = f"{cfg.name}-{number:03d}"
    f = exc.finding
    how = how or ("shrunk by hypothesis" if shrunk else "not shrunk: the box hung, each shrink step would wait time_out")
    message = f"{f.requirement}; the box {f.observed} (session of {len(exc.steps)} steps, {how})"
    clauses = clauses_of(exc.case, [f.clause])
    if f.key.startswith(DEATH_KEY):  # the death first, then the trigger's clauses
        clauses = ["R2", *(c for c in clauses if c != "R2")]
    failure = Failure(number, "stateful", clauses, message, [exc.case] if exc.case.data else [],
                      shrunk=shrunk, steps=exc.steps, keys=[f.key] if f.key else [], last_words=words)
    desc = f"isight-conformance fuzz: session failure {number} against {cfg.target} (seed {campaign_seed})"
    if failure.cases and cfg.report_dir is not None:
        failure.vector = write_vectors(cfg.report_dir / f"{name}.json", failure, cfg.profile, desc)
    if cfg.report_dir is not None:
        failure.sequence = write_sequence(cfg.report_dir / f"{name}.sequence.json", number, failure, exc.sequence)
    if cfg.capture != "off" and cfg.pcap_dir is not None:
        failure.pcap = write_pcap(exc.transcript, cfg.pcap_dir / f"{name}.pcapng")
    cfg.log(f"fuzz: FAIL {number} [{', '.join(failure.clauses)}] {message}\n      steps: "
            + "; ".join(exc.steps) + f"\n      sequence: {failure.sequence}"
            + (f"\n      vector: {failure.vector}" if failure.vector else "")
            + (f"\n      pcap: {failure.pcap}" if failure.pcap else "")
            + (f"\n      box: {words.summary()}" if words is not None else ""))
    return failure


__all__ = ["RUNS_PER_CHUNK", "STEPS", "SessionRunner", "StatefulFailure", "StatefulResult", "run_stateful"]
