"""Fuzz campaigns: hypothesis generates and shrinks, the executor sends, the oracle judges.

The campaign runs hypothesis in *chunks*: each chunk is one ``@given`` run of
``chunk_examples`` examples, with its own seed derived from the campaign's seed (so
``--seed`` makes the whole campaign repeat) and the same database key (so a failure
found once is replayed first next time). One hypothesis example is a *batch*: a list
of up to ``batch`` fuzz cases, run one after the other on a reused connection;
hypothesis pays its per-example overhead once per batch, and shrinks a failing batch
down to the one case that fails and that case down to its simplest frame. After each
hypothesis case ``mutants`` cheap mutants of the recent ones run (:mod:`.mutants`: hypothesis's
engine, not the box, is what a case costs), and after each drawn case and each mutant one
case of the boundary schedule (:mod:`.schedule`), until the schedule is done: every block
count, field boundary and float class early.

Frame chunks alternate with chunks of the session state machine (:mod:`.session_runner`)
from the first second, so that the sessions get ``stateful_share`` of the time (or of
the cases) all along. Between chunks the campaign checks its budget
(``max_examples`` cases or ``duration_s``).

This module is the loop. A failing case is confirmed, shrunk, stated plainly and
written by :mod:`.triage`; a box that *dies* (R2) is brought back, and :mod:`.death`
finds which input (or sequence) killed it; the campaign then goes on, or stops when
the box does not come back.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections import deque

from hypothesis import HealthCheck, Phase, Verbosity, given, settings
from hypothesis import strategies as st
from hypothesis.errors import Flaky

from .. import __version__
from ..evidence.pcap import PcapRecorder
from ..harness.client import Silence
from ..harness.transcript import Transcript
from ..model.verdicts import Verdict
from ..runtime.profile_options import profile_flags
from . import second_look
from .budget import Budget
from .config import CampaignConfig, new_seed
from .death import RESTART_HINT, STOPPED, Seen, death_key, find_killer
from .executor import Executor, Result, alive
from .failure_files import Failure, write_summary
from .hyp import seed_test, set_database_key
from .input_coverage import Coverage
from .mutants import Mutants
from .restart import recover
from .result import CampaignResult, Observation, Sessions
from .schedule import Schedule
from .session_runner import SessionRunner
from .strategies import FuzzCase, Strategies
from .triage import FuzzFailure, Triage

#: Cases per campaign pcap file when every case is recorded (``capture="all"``).
SEGMENT_CASES = 20_000
#: Events kept in memory per campaign transcript (the pcap has them all).
KEEP_EVENTS = 20_000
#: Mutants after which the box waited time_out without failing (a legal framing of their bytes) before the
#: campaign sends no more mutants.
MUTANT_SILENCES = 3


class Campaign:
    """``Campaign(config).run()``: the :class:`CampaignResult` (also written to ``fuzz-summary.json``)."""

    def __init__(self, config: CampaignConfig) -> None:
        cfg = self.config = config
        self.seed = cfg.seed if cfg.seed is not None else new_seed()
        self.examples = 0
        self.non_strict: dict[str, Observation] = {}
        self.stopped = ""
        self.strategies = Strategies(cfg.profile, cfg.extension, udp=cfg.udp_target is not None)
        self.cases = self.strategies.cases(cfg.categories)
        self.schedule = Schedule(self.strategies) if not cfg.categories else None
        self.mutants = Mutants(self.strategies, self.seed ^ 0x6D757461) if not cfg.categories and cfg.mutants else None
        self._mutant_silences = 0
        self.coverage = Coverage(cfg.profile)
        self.disabled: set[str] = set()
        self.window: list[Seen] = []  # cases since the last good liveness check
        self.history: deque[FuzzCase] = deque(maxlen=16)  # cases on the current reused connection
        self.budget = Budget(cfg)
        self.started = self.budget.started
        self.started_wall = time.time()
        self.restarts = 0
        self.internal_error: Exception | None = None
        self._segment = 0
        self._segment_cases = 0
        self._recorder: PcapRecorder | None = None
        self._last_progress = self.started
        self.transcript = self._new_segment()
        self.executor = Executor(
            cfg.target, cfg.profile, self.transcript, udp_target=cfg.udp_target, extension=cfg.extension,
            liveness_every=cfg.liveness_every, settle_s=cfg.settle_s,
        )
        self.triage = Triage(cfg, self.seed, self.strategies, self.executor, lambda: self.examples,
                             self.budget.elapsed)
        self.sessions = SessionRunner(cfg, self.strategies, self.seed, self._sessions_left,
                                      lambda: self.triage.next_number, self._bring_back) \
            if cfg.stateful_share > 0 else None
        self.digest = f"isight-fuzz/frames/{sorted(cfg.profile.to_dict().items())}/{cfg.extension}/" \
                      f"{cfg.udp_target is not None}/{cfg.categories}".encode()

    @property
    def failures(self) -> list[Failure]:
        return self.triage.failures

    # -- budget ----------------------------------------------------------------------------
    def _going(self) -> bool:
        if self.config.until_first and not self.stopped and any(f.confirmed for f in self.failures):
            self.stopped = "the first confirmed finding (--until-first)"
            self.config.log(f"fuzz: stopping at {self.stopped}")
        return not self.stopped and len(self.failures) < self.config.max_failures

    def budget_left(self) -> bool:
        """May another frame case run?"""
        return self._going() and self.budget.frames_left(self.examples)

    def _steps(self) -> int:
        return self.sessions.ctx.steps if self.sessions is not None else 0

    def _sessions_left(self) -> bool:
        return self._going() and self.budget.sessions_left(self._steps())

    # -- running ---------------------------------------------------------------------------
    def run(self) -> CampaignResult:
        cfg = self.config
        target_flag = [] if cfg.bundled else [f"--target {cfg.target}"]
        rerun = " ".join(["isight-conformance fuzz", *target_flag, *profile_flags(cfg.profile), f"--seed {self.seed}"])
        cfg.log(f"fuzz: seed {self.seed} (rerun with: {rerun}); target {cfg.target}"
                + (f", UDP {cfg.udp_target}" if cfg.udp_target else "")
                + f"; profile {cfg.profile.describe()}; extension {'on' if cfg.extension else 'off'}; "
                f"database {cfg.database_label}")
        if cfg.max_examples is None and cfg.duration_s is None:
            raise ValueError("give a budget: max_examples or duration_s")
        chunk = 0
        try:
            while self._going():
                part = self.budget.next_part(self.examples, self._steps(), self._sessions_possible())
                if part is None:
                    break
                with self.budget.timing(part):
                    if part == "sessions":
                        self._session_chunk()
                    else:
                        self._run_chunk(chunk)
                        chunk += 1
        finally:
            self.executor.close()
            if self._recorder is not None:
                self._recorder.close()
        result = self.result()
        if cfg.report_dir is not None:
            write_summary(cfg.report_dir / "fuzz-summary.json", result.to_dict())
        return result

    def _sessions_possible(self) -> bool:
        return self.sessions is not None and not self.sessions.stopped

    def _session_chunk(self) -> None:
        assert self.sessions is not None
        for failure in self.sessions.run_chunk():
            failure.found_after = self.examples
            failure.found_s = self.budget.elapsed()
            self.failures.append(failure)
        if self.sessions.stopped == "dead":
            self.stopped = STOPPED
        elif self.sessions.stopped:
            self.sessions.stopped = ""  # a failure was recorded: the sessions go on (it is known now)

    def _chunk_seed(self, chunk: int) -> int:
        return (self.seed * 1_000_003 + chunk) % (2**63)

    def _run_chunk(self, chunk: int) -> None:
        cfg = self.config
        phases = [Phase.generate, Phase.shrink]
        if chunk == 0 and cfg.database is not None:
            phases.insert(0, Phase.reuse)
        hyp = settings(
            max_examples=cfg.chunk_examples, deadline=None, database=cfg.database, phases=phases,
            suppress_health_check=list(HealthCheck), report_multiple_bugs=False, derandomize=False,
            verbosity=Verbosity.quiet, print_blob=False,
        )

        def fuzz_frames(batch: list[FuzzCase]) -> None:
            try:
                failing = self._execute(batch)
            except Exception as exc:  # the suite's own fault: stop, and never let hypothesis shrink it
                self.stopped = f"internal error: {type(exc).__name__}: {exc}"
                self.internal_error = exc
                return
            if failing is not None:  # one raise site: hypothesis tells failures apart by where they are raised
                raise FuzzFailure(failing)

        test = hyp(given(st.lists(self.cases, min_size=1, max_size=cfg.batch))(fuzz_frames))
        seed_test(test, self._chunk_seed(chunk))
        set_database_key(test, self.digest)
        self.triage.shrinking = False
        try:
            test()
        except FuzzFailure as exc:
            self.triage.record_shrunk(exc.result)
        except Flaky as exc:
            self.config.log(f"fuzz: a failure did not reproduce when hypothesis replayed it ({type(exc).__name__}); "
                            "it is recorded as found, unshrunk")
            if not self.stopped:
                self.triage.record_pending()
        finally:
            self.triage.end_shrink()
            self._after_chunk()
        if self.internal_error is not None:
            raise self.internal_error

    def _after_chunk(self) -> None:
        if self.config.transcript is not None:
            return  # not ours to trim or rotate
        events = self.transcript.events
        if len(events) > KEEP_EVENTS:
            with self.transcript._lock:  # noqa: SLF001 - trimming our own transcript's memory
                del events[: len(events) - KEEP_EVENTS]
        if self.config.capture == "all" and self._segment_cases >= SEGMENT_CASES:
            self.executor.close()
            self.transcript = self.executor.transcript = self._new_segment()

    def _new_segment(self) -> Transcript:
        if self.config.transcript is not None:
            return self.config.transcript
        if self._recorder is not None:
            self._recorder.close()
            self._recorder = None
        self._segment += 1
        self._segment_cases = 0
        tr = Transcript(case_id=f"FUZZ-campaign-{self._segment:03d}")
        cfg = self.config
        if cfg.capture == "all" and cfg.pcap_dir is not None:
            self._recorder = PcapRecorder.attach(tr, cfg.pcap_dir / f"campaign-{self._segment:03d}.pcapng")
        return tr

    def _execute(self, batch: list[FuzzCase]) -> Result | None:
        """Run a batch (a scheduled case after each of its cases); the confirmed failure to raise to hypothesis."""
        triage = self.triage
        for case in batch:
            if self.stopped or (not triage.shrinking and not self.budget_left()):
                return None
            if case.kind in self.disabled:
                continue
            raised = self._step(case, shrinkable=True)
            if raised is not None:
                return raised
            if not triage.shrinking:
                self._scheduled()
            if not triage.shrinking and self.mutants is not None:
                self._mutants(case)
        return None

    def _scheduled(self) -> None:
        """The next case of the boundary schedule (after every case drawn or derived, until it is done)."""
        if self.schedule is not None and self.budget_left():
            scheduled = self.schedule.next()
            if scheduled is not None and scheduled.kind not in self.disabled:
                self._step(scheduled, shrinkable=False)

    def _mutants(self, drawn: FuzzCase) -> None:
        """``config.mutants`` cheap cases derived from the recent hypothesis cases (:mod:`.mutants`), each followed
        by a case of the schedule: the schedule keeps half of the cases until it is done."""
        assert self.mutants is not None
        self.mutants.feed(drawn)
        for _ in range(self.config.mutants):
            if self.stopped or not self.budget_left():
                return
            mutant = self.mutants.next()
            if mutant is None or mutant.kind in self.disabled:
                continue
            self._step(mutant, shrinkable=False)
            self._scheduled()

    def _step(self, case: FuzzCase, shrinkable: bool) -> Result | None:
        """One case: run, judged, confirmed if it fails; the result to raise to hypothesis (``shrinkable`` only)."""
        ex, triage = self.executor, self.triage
        result = ex.run(case)
        self._segment_cases += 1
        if triage.shrinking:
            triage.shrink_runs += 1
        else:
            self.examples += 1
            self.coverage.observe(case)
        self.history.append(case)
        self.window.append(Seen(case, result))
        if result.liveness is not None:
            if not alive(result.liveness):
                self._on_death()
                return None
            self.window = []
        self._progress()
        self._observe(case, result)
        failing = triage.new_failures(result)
        if case.kind == "mutant" and len(failing) < len(result.judgement.failures):
            failing = []  # a mutant failing a way already reported, among others, shows the same defect again
        if not failing:
            if result.anomaly:
                self.history.clear()
            return None
        if triage.shrinking:
            return result
        history = list(self.history)  # the cases on this connection, before the confirmation run clears it
        confirmed = triage.confirm(case)
        self.history.clear()
        if confirmed.liveness is not None and not alive(confirmed.liveness):
            self.window.append(Seen(case, confirmed))
            self._on_death()
            return None
        keys = {f.key for f in failing}
        if shrinkable:
            return triage.route(result, confirmed, keys, history)
        triage.settle(result, confirmed, keys, history)
        return None

    def _on_death(self) -> None:
        window, self.window = self.window, []
        self.history.clear()
        death = find_killer(self.config, window, self.executor, self.triage.next_number)
        ex = self.executor
        where = second_look.Where(ex.transcript, ex.target, ex.profile, ex.time_out_s, ex.stats.cases)
        if second_look.stall_not_death(where, self.config.restart is not None, death.failure.confirmed, death.back,
                                       window[-1].case.wire if window else b""):
            self.config.log("fuzz: the whole box stalled and came back on its own (T1/S4): not a death")
            return
        key = death_key(death.failure)
        if key in self.triage.known:
            self.config.log("fuzz: the box died again the way it did before (not reported twice)")
        else:
            self.triage.known.add(key)
            death.failure.keys.append(key)
            self.triage.write(death.failure, death.evidence if death.evidence is not None else self.transcript)
        if death.back:
            self.restarts += 1
            self.config.log("fuzz: the box is back; the campaign goes on")
        else:
            self.stopped = STOPPED

    def _bring_back(self) -> bool:
        """A session left the box dead: bring it back (False: it did not come back)."""
        back = recover(self.config, self.executor)
        self.restarts += back
        self.executor.drop_connection()  # a restart may have cut the frames' reused connection: not the box's fault
        self.history.clear()
        return back

    def _observe(self, case: FuzzCase, result: Result) -> None:
        if case.kind == "mutant" and isinstance(result.end, Silence) and result.verdict is not Verdict.FAIL:
            self._mutant_silences += 1  # the box framed the bytes otherwise (R6 allows it) and waits on them
            if self._mutant_silences >= MUTANT_SILENCES:
                self.disabled.add(case.kind)
                self.config.log(f"fuzz: the box waited time_out on {MUTANT_SILENCES} mutants (it frames some bytes "
                                "otherwise, as R6 allows); no more mutants in this campaign (each would wait time_out)")
        if case.kind == "R5-oversized" and isinstance(result.end, Silence) and case.kind not in self.disabled:
            self.disabled.add(case.kind)  # legal (R6 a: it skips what the header announces), but each waits time_out
            self.config.log(f"fuzz: the box waits on a {case.kind} header (R6 a trusts it and skips what it "
                            f"announces); {case.kind} cases are not sent again in this campaign (each would wait time_out)")
        for f in result.judgement.findings:
            if f.verdict is not Verdict.NON_STRICT:
                continue
            seen = self.non_strict.get(f.key)
            if seen is not None:
                seen.count += 1
                continue
            self.non_strict[f.key] = Observation(f.clause, f.requirement, f.observed, case.kind, case.wire.hex(),
                                                 key=f.key)
            if f.key in ("end/hang",) or f.clause == "S5":
                self.disabled.add(case.kind)
                self.config.log(f"fuzz: NON-STRICT [{f.clause}] the box hung on a {case.kind} case; "
                                f"{case.kind} cases are not sent again in this campaign (each would wait time_out)")

    def _progress(self) -> None:
        now = time.monotonic()
        if now - self._last_progress < self.config.progress_s:
            return
        self._last_progress = now
        rate = (self.examples + self.triage.shrink_runs) / max(1e-9, now - self.started)
        self.config.log(f"fuzz: {self.examples:,} examples ({rate:,.0f}/s), {self._steps():,} session steps, "
                        f"{len(self.failures)} failures, {len(self.non_strict)} kinds of NON-STRICT")

    # -- the result ---------------------------------------------------------------------------
    def result(self) -> CampaignResult:
        cfg = self.config
        stats = self.executor.stats
        shrink_runs = self.triage.shrink_runs
        frames_s = self.budget.spent["frames"]
        s = self.sessions
        sessions = Sessions(s.ctx.runs, s.ctx.steps, s.coverage.to_dict()) if s is not None else Sessions()
        dead_hint = any(f.kind == "death" and not f.confirmed for f in self.failures) and cfg.restart is None
        return CampaignResult(
            tool=f"isight-conformance {__version__} fuzz", command=cfg.command, seed=self.seed,
            rerun=f"add --seed {self.seed} (with --database none the campaign repeats exactly)",
            target=str(cfg.target), udp_target=str(cfg.udp_target) if cfg.udp_target else None,
            profile=cfg.profile.to_dict(), extension=cfg.extension, database=cfg.database_label,
            started=_dt.datetime.fromtimestamp(self.started_wall, _dt.timezone.utc).isoformat(timespec="seconds"),
            duration_s=round(self.budget.elapsed(), 3), examples=self.examples,
            examples_per_s=round((self.examples + shrink_runs) / frames_s, 1) if frames_s else None,
            shrink_runs=shrink_runs, scheduled=self.schedule.sent if self.schedule is not None else 0,
            coverage=self.coverage.to_dict(), stateful=sessions, connections=stats.connections,
            liveness_checks=stats.liveness_checks, restarts=self.restarts, by_kind=dict(sorted(stats.by_kind.items())),
            disabled_kinds=sorted(self.disabled), stopped=self.stopped or None, failures=list(self.failures),
            non_strict=list(self.non_strict.values()), hint=RESTART_HINT if dead_hint else "",
        )


__all__ = ["KEEP_EVENTS", "SEGMENT_CASES", "Campaign", "CampaignConfig", "CampaignResult", "Observation"]
