"""Fuzz campaigns: hypothesis generates and shrinks, the executor sends, the oracle judges.

The campaign runs hypothesis in *chunks*: each chunk is one ``@given`` run of
``chunk_examples`` examples, with its own seed derived from the campaign's seed (so
``--seed`` makes the whole campaign repeat) and the same database key (so a failure
found once is replayed first next time). One hypothesis example is a *batch*: a list
of up to ``batch`` fuzz cases, run one after the other on a reused connection;
hypothesis pays its per-example overhead once per batch, and shrinks a failing batch
down to the one case that fails and that case down to its simplest frame. Between
chunks the campaign checks its budget (``max_examples`` cases or ``duration_s``).

A failing case is confirmed on a fresh connection before hypothesis sees it (what
a box did with an earlier case on a reused connection must not be blamed on a later
one), then raised; hypothesis shrinks it (every case isolated on its own connection
while it does), and the campaign reruns the minimal case once more on a fresh
transcript: that run is the evidence (vector file, pcap). Distinct failures are told
apart by what failed (clause, rule, action): once one is recorded, examples failing
the same way no longer count, so the campaign goes on to find others.

Not shrunk by hypothesis: a box that *dies* (R2) — the campaign stops, finds the
killing case among those since the last good liveness check by rerunning each on a
fresh connection followed by a liveness check (after a restart of the bundled box,
or once the box is back), and writes it; a *hang* (no answer within time_out), which
would cost time_out per shrink step; and a failure that only happens on a reused
connection (written as the cases sent on that connection, in order).
"""

from __future__ import annotations

import datetime as _dt
import random
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, Phase, Verbosity, given, seed, settings
from hypothesis import strategies as st
from hypothesis.database import ExampleDatabase
from hypothesis.errors import Flaky

from .. import __version__
from ..evidence.pcap import PcapRecorder
from ..harness.client import Silence
from ..harness.target import Target
from ..harness.transcript import Transcript
from ..options import profile_flags
from ..protocol import DEFAULT_PROFILE, Profile
from ..suite.verdicts import Verdict
from .evidence import Failure, clauses_of, write_pcap, write_summary, write_vectors
from .executor import Executor, Result, alive
from .strategies import FuzzCase, Strategies

#: Cases per campaign pcap file when every case is recorded (``capture="all"``).
SEGMENT_CASES = 20_000
#: Events kept in memory per campaign transcript (the pcap has them all).
KEEP_EVENTS = 20_000
#: The strategy (category, kind prefix) that states a failure of a clause most plainly.
PLAIN = {
    "valid": ("valid", "valid"), "B3": ("B3-index", "B3"), "B4": ("B4-floats", "B4"), "F1": ("F1-start-word", "F1-start"),
    "F2": ("F2-version", "F2"), "F3": ("F3-direction", "F3"), "A5": ("A5-unknown-action", "A5"),
    "F6": ("F6-check", "F6"), **{c: ("B5-shape", "B5") for c in ("B1", "B2", "B5", "E1", "E2", "E3")},
}
#: At most this many cases are spent looking for a plainer example of a failure.
REDERIVE_EXAMPLES = 300


class FuzzFailure(Exception):
    """Raised inside the hypothesis test for a confirmed failing case (hypothesis shrinks it)."""

    def __init__(self, result: Result) -> None:
        super().__init__(result.judgement.describe())
        self.result = result


@dataclass
class CampaignConfig:
    target: Target
    profile: Profile = DEFAULT_PROFILE
    udp_target: Target | None = None
    stream_target: Target | None = None
    seed: int | None = None
    max_examples: int | None = None  # fuzz cases (frames); stateful steps come on top of the share
    duration_s: float | None = None
    report_dir: Path | None = Path("reports/fuzz")  # None: no files (the suite's case keeps its own evidence)
    pcap_dir: Path | None = None
    capture: str = "failures"  # failures | all | off
    database: ExampleDatabase | None = None
    database_label: str = "off"
    extension: bool = True
    batch: int = 32
    liveness_every: int = 64
    max_failures: int = 5
    categories: tuple[str, ...] = ()
    stateful_share: float = 0.2  # of the budget for the session state machine (0: off)
    restart: Callable[[], None] | None = None  # brings a dead box back (the bundled box)
    recover_s: float | None = None  # how long to wait for a dead box to come back (default: time_out)
    chunk_examples: int = 100
    settle_s: float = 0.05
    progress_s: float = 2.0
    log: Callable[[str], None] = print
    command: str = ""
    transcript: Transcript | None = None  # record into this transcript (a case's) instead of the campaign's own
    name: str = "fuzz-failure"  # file names: <name>-001.json, <name>-001.pcapng
    bundled: bool = False  # the target is the bundled box this command started (the rerun hint omits --target)

    def __post_init__(self) -> None:
        if self.capture not in ("failures", "all", "off"):
            raise ValueError("capture must be failures, all or off")
        if not 0 <= self.stateful_share <= 1:
            raise ValueError("the stateful share must be between 0 and 1")
        if self.max_examples is not None and self.max_examples < 1:
            raise ValueError("--max-examples must be at least 1")
        if self.duration_s is not None and self.duration_s <= 0:
            raise ValueError("--duration must be positive")
        if self.batch < 1 or self.liveness_every < 1 or self.chunk_examples < 1:
            raise ValueError("batch, liveness interval and chunk size must be at least 1")


def new_seed() -> int:
    return random.SystemRandom().randrange(1, 2**32)


@dataclass
class Observation:
    """A SHOULD the box broke (NON-STRICT), first seen on ``hex``."""

    clause: str
    requirement: str
    observed: str
    kind: str
    hex: str
    count: int = 1


@dataclass
class _Seen:
    case: FuzzCase
    result: Result


@dataclass
class Campaign:
    config: CampaignConfig
    seed: int = 0
    examples: int = 0
    shrink_runs: int = 0
    failures: list[Failure] = field(default_factory=list)
    non_strict: dict[str, Observation] = field(default_factory=dict)
    stopped: str = ""

    def __post_init__(self) -> None:
        cfg = self.config
        self.seed = cfg.seed if cfg.seed is not None else new_seed()
        self.strategies = Strategies(cfg.profile, cfg.extension, udp=cfg.udp_target is not None)
        self.cases = self.strategies.cases(cfg.categories)
        self.known: set[str] = set()
        self.disabled: set[str] = set()
        self.window: list[_Seen] = []  # cases since the last good liveness check
        self.history: deque[FuzzCase] = deque(maxlen=16)  # cases on the current reused connection
        self.shrinking = False
        self.started = time.monotonic()
        self.started_wall = time.time()
        self.frames_s = 0.0
        self.stateful_steps = 0
        self.stateful_runs = 0
        self.stateful_started = 0.0
        self.stateful_shrinking = False
        self.known_before_shrink: set[str] = set()
        self.pending: Result | None = None  # the confirmed failure hypothesis is shrinking
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
        self.digest = f"isight-fuzz/frames/{sorted(cfg.profile.to_dict().items())}/{cfg.extension}/" \
                      f"{cfg.udp_target is not None}/{cfg.categories}".encode()

    # -- budget ----------------------------------------------------------------------------
    @property
    def frames_budget(self) -> int | None:
        cfg = self.config
        if cfg.max_examples is None:
            return None
        frames = round(cfg.max_examples * (1 - cfg.stateful_share))
        return frames if cfg.stateful_share >= 1 else max(1, frames)

    def _frames_time(self) -> float | None:
        d = self.config.duration_s
        return None if d is None else d * (1 - self.config.stateful_share)

    def budget_left(self) -> bool:
        if self.stopped or len(self.failures) >= self.config.max_failures:
            return False
        budget = self.frames_budget
        if budget is not None and self.examples >= budget:
            return False
        limit = self._frames_time()
        return limit is None or time.monotonic() - self.started < limit

    def stateful_left(self) -> bool:
        cfg = self.config
        if self.stopped or len(self.failures) >= cfg.max_failures:
            return False
        if cfg.max_examples is not None and self.stateful_steps >= max(1, cfg.max_examples - (self.frames_budget or 0)):
            return False
        if cfg.duration_s is not None:
            return time.monotonic() - self.stateful_started < cfg.duration_s * cfg.stateful_share
        return True

    # -- running ---------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        cfg = self.config
        target_flag = [] if cfg.bundled else [f"--target {cfg.target}"]
        rerun = " ".join(["isight-conformance fuzz", *target_flag, *profile_flags(cfg.profile), f"--seed {self.seed}"])
        cfg.log(f"fuzz: seed {self.seed} (rerun with: {rerun}); target {cfg.target}"
                + (f", UDP {cfg.udp_target}" if cfg.udp_target else "")
                + f"; profile {cfg.profile.describe()}; extension {'on' if cfg.extension else 'off'}; "
                f"database {cfg.database_label}")
        if cfg.max_examples is None and cfg.duration_s is None:
            raise ValueError("give a budget: max_examples or duration_s")
        start = time.monotonic()
        chunk = 0
        try:
            while self.budget_left():
                self._run_chunk(chunk)
                chunk += 1
            self.frames_s = time.monotonic() - start
            if cfg.stateful_share > 0 and not self.stopped and len(self.failures) < cfg.max_failures:
                from .stateful import run_stateful

                run_stateful(self)
        finally:
            self.executor.close()
            if self._recorder is not None:
                self._recorder.close()
        if not self.frames_s:
            self.frames_s = time.monotonic() - start
        summary = self.summary()
        if cfg.report_dir is not None:
            write_summary(cfg.report_dir / "fuzz-summary.json", summary)
        return summary

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
        # What @seed sets, without what @seed also does: switch the example database off.
        test._hypothesis_internal_use_seed = self._chunk_seed(chunk)  # type: ignore[attr-defined]
        test.hypothesis.inner_test._hypothesis_internal_add_digest = self.digest  # type: ignore[attr-defined]
        self.shrinking = False
        try:
            test()
        except FuzzFailure as exc:
            self._record_shrunk(exc.result)
        except Flaky as exc:
            self.config.log(f"fuzz: a failure did not reproduce when hypothesis replayed it ({type(exc).__name__}); "
                            "it is recorded as found, unshrunk")
            if self.pending is not None and not self.stopped:
                self._record(self.pending, "oracle", shrunk=False)
                self.known |= self.known_before_shrink
        finally:
            self.pending = None
            self.shrinking = False
            self.executor.isolate = self.executor.settle = False
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
        """Run a batch; the result of a confirmed failure to raise to hypothesis, else None."""
        ex = self.executor
        for case in batch:
            if self.stopped or (not self.shrinking and not self.budget_left()):
                return None
            if case.kind in self.disabled:
                continue
            result = ex.run(case)
            self._segment_cases += 1
            if self.shrinking:
                self.shrink_runs += 1
            else:
                self.examples += 1
            self.history.append(case)
            self.window.append(_Seen(case, result))
            if result.liveness is not None:
                if not alive(result.liveness):
                    self._on_death()
                    return None
                self.window = []
            self._progress()
            self._observe(case, result)
            failing = [f for f in result.judgement.failures if f.key not in self.known]
            if not failing:
                if result.anomaly:
                    self.history.clear()
                continue
            if self.shrinking:
                return result
            confirmed = self._confirm(case)
            if confirmed.liveness is not None and not alive(confirmed.liveness):
                self.window.append(_Seen(case, confirmed))
                self._on_death()
                return None
            keys = {f.key for f in failing}
            if not [f for f in confirmed.judgement.failures if f.key not in self.known]:
                self._record_context(result, list(self.history))
                self.known |= keys
                continue
            if isinstance(confirmed.end, Silence):  # a hang: shrinking would wait time_out per step
                self._record(confirmed, "oracle", shrunk=False)
                self.known |= keys
                continue
            self.known_before_shrink = keys
            self.pending = confirmed
            self.shrinking = True
            ex.isolate = True
            return confirmed
        return None

    def _confirm(self, case: FuzzCase) -> Result:
        ex = self.executor
        ex.isolate = ex.settle = True
        try:
            return ex.run(case, f"confirming on a fresh connection: {case.describe()}")
        finally:
            ex.isolate = ex.settle = False
            ex.drop_connection()
            self.history.clear()

    def _observe(self, case: FuzzCase, result: Result) -> None:
        for f in result.judgement.findings:
            if f.verdict is not Verdict.NON_STRICT:
                continue
            seen = self.non_strict.get(f.key)
            if seen is not None:
                seen.count += 1
                continue
            self.non_strict[f.key] = Observation(f.clause, f.requirement, f.observed, case.kind, case.wire.hex())
            if f.key in ("end/hang",) or f.clause == "S5":
                self.disabled.add(case.kind)
                self.config.log(f"fuzz: NON-STRICT [{f.clause}] the box hung on a {case.kind} case; "
                                f"{case.kind} cases are not sent again in this campaign (each would wait time_out)")

    def _progress(self) -> None:
        now = time.monotonic()
        if now - self._last_progress < self.config.progress_s:
            return
        self._last_progress = now
        rate = (self.examples + self.shrink_runs) / max(1e-9, now - self.started)
        self.config.log(f"fuzz: {self.examples:,} examples ({rate:,.0f}/s), {len(self.failures)} failures, "
                        f"{len(self.non_strict)} kinds of NON-STRICT")

    # -- recording -------------------------------------------------------------------------
    def _evidence_run(self, case: FuzzCase, number: int) -> tuple[Result, Transcript]:
        tr = Transcript(case_id=f"FUZZ-{number:03d}")
        cfg = self.config
        ex = Executor(cfg.target, cfg.profile, tr, udp_target=cfg.udp_target, extension=cfg.extension,
                      settle_s=cfg.settle_s)
        ex.isolate = ex.settle = True
        try:
            result = ex.run(case, f"fuzz failure {number}: {case.describe()}")
            if result.liveness is None:
                result.liveness = ex.check_alive()
        finally:
            ex.close()
        return result, tr

    def _record_shrunk(self, result: Result) -> None:
        plainer = self._rederive(result)
        self._record(plainer or result, "oracle", shrunk=True)
        self.known |= self.known_before_shrink

    def _rederive(self, result: Result) -> Result | None:
        """The same failure from the strategy that states it most plainly, shrunk, if that is no longer.

        Hypothesis shrinks within the strategy that found a failure: one found by a
        byte-level mutation stays a mutation (shrinking cannot jump to another branch of
        the ``one_of`` when the bytes after it change meaning). So a failure whose case is
        not from its clause's own strategy is searched for again with that strategy alone
        (at most ``REDERIVE_EXAMPLES`` cases, isolated) and the shorter of the two is kept."""
        keys = {f.key for f in result.judgement.failures}
        clause = sorted(k.split("/")[0] for k in keys)[0] if keys else ""
        category, prefix = PLAIN.get(clause, ("", ""))
        if not category or category not in self.strategies.categories() or result.case.kind.startswith(prefix):
            return None
        ex = self.executor
        found: list[Result] = []

        def plain(case: FuzzCase) -> None:
            self.shrink_runs += 1
            r = ex.run(case, f"the same failure from the {category} strategy? {case.describe()}")
            if {f.key for f in r.judgement.failures} & keys:
                found.append(r)
                raise FuzzFailure(r)

        test = seed(self.seed ^ 0x5EED)(settings(
            max_examples=REDERIVE_EXAMPLES, deadline=None, database=None, phases=[Phase.generate, Phase.shrink],
            suppress_health_check=list(HealthCheck), report_multiple_bugs=False, derandomize=False,
            verbosity=Verbosity.quiet, print_blob=False,
        )(given(self.strategies.cases((category,)))(plain)))
        ex.isolate = True
        try:
            test()
        except FuzzFailure as exc:
            if len(exc.result.case.wire) <= len(result.case.wire):
                return exc.result
        except Flaky:
            pass
        finally:
            ex.isolate = False
        return None

    def _record(self, result: Result, kind: str, shrunk: bool) -> Failure:
        number = len(self.failures) + 1
        case = result.case
        evidence, tr = self._evidence_run(case, number)
        reproduced = bool(evidence.judgement.failures)
        best = evidence if reproduced else result
        first = best.judgement.failures[0] if best.judgement.failures else result.judgement.failures[0]
        message = f"{first.requirement}; the box {best.observed()}"
        if not reproduced:
            message += " (the evidence run on a fresh connection did not reproduce it)"
        failure = Failure(number, kind, clauses_of(case, [f.clause for f in best.judgement.failures]), message,
                          [case], shrunk=shrunk, confirmed=reproduced)
        self.known |= {f.key for f in result.judgement.failures} | {f.key for f in evidence.judgement.failures}
        return self._write(failure, tr)

    def _record_context(self, result: Result, history: list[FuzzCase]) -> None:
        number = len(self.failures) + 1
        first = result.judgement.failures[0]
        message = (f"{first.requirement}; the box {result.observed()} — only after the cases before it on the same "
                   "connection (on a fresh connection the last case passes)")
        failure = Failure(number, "context", clauses_of(result.case, [first.clause]), message, history or [result.case],
                          confirmed=False)
        self._write(failure, self.transcript)

    def _write(self, failure: Failure, transcript: Transcript) -> Failure:
        cfg = self.config
        name = f"{cfg.name}-{failure.number:03d}"
        desc = (f"isight-conformance {__version__} fuzz: failure {failure.number} against {cfg.target} "
                f"(seed {self.seed}, profile {cfg.profile.describe()})")
        failure.found_after = self.examples
        if cfg.report_dir is not None:
            failure.vector = write_vectors(cfg.report_dir / f"{name}.json", failure, cfg.profile, desc)
        if cfg.capture != "off" and cfg.pcap_dir is not None:
            failure.pcap = write_pcap(transcript, cfg.pcap_dir / f"{name}.pcapng")
        self.failures.append(failure)
        cfg.log(f"fuzz: FAIL {failure.number} [{', '.join(failure.clauses)}] {failure.message}\n"
                f"      bytes: {failure.hex}" + (f"\n      vector: {failure.vector}" if failure.vector else "")
                + (f"\n      pcap: {failure.pcap}" if failure.pcap else ""))
        return failure

    # -- R2: a box that dies ------------------------------------------------------------------
    def _recover(self) -> bool:
        cfg = self.config
        if cfg.restart is not None:
            try:
                cfg.restart()
            except Exception as exc:  # noqa: BLE001 - reported, the campaign stops anyway
                cfg.log(f"fuzz: could not restart the box: {exc}")
                return False
        wait = cfg.recover_s if cfg.recover_s is not None else self.executor.time_out_s
        deadline = time.monotonic() + wait
        while True:
            if alive(self.executor.check_alive()):
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.1)

    def _on_death(self) -> None:
        cfg = self.config
        window = self.window
        self.window = []
        self.stopped = "the box stopped answering new connections (R2)"
        suspects = [s.case for s in window]
        prime = next((s.case for s in window if s.result.anomaly), None)
        cfg.log(f"fuzz: R2: the box no longer answers a fresh connection; {len(suspects)} cases since the last good "
                "liveness check are suspects")
        ex = self.executor
        ex.close()
        number = len(self.failures) + 1
        killer: FuzzCase | None = None
        evidence = self.transcript
        if self._recover():
            tr = Transcript(case_id=f"FUZZ-{number:03d}")
            probe = Executor(cfg.target, cfg.profile, tr, udp_target=cfg.udp_target, extension=cfg.extension,
                             liveness_every=1)
            probe.isolate = True
            order = ([prime] if prime is not None else []) + [c for c in suspects if c is not prime]
            for case in order:
                result = probe.run(case, f"is this the case that kills the box? {case.describe()}")
                if result.liveness is not None and not alive(result.liveness):
                    killer = case
                    break
            probe.close()
            evidence = tr
            if killer is not None:
                self._recover()
        confirmed = killer is not None
        if killer is None and prime is not None:
            killer = prime
        cases = [killer] if killer is not None else suspects
        if confirmed:
            how = "rerun on its own after the box came back, it killed the box again"
        elif killer is not None:
            how = "the box closed or stopped answering right after it (not confirmed: the box did not come back)"
        else:
            how = "one of these cases (the box did not come back to tell which)"
        message = f"R2: after this input the box no longer accepts and answers new connections; {how}"
        clauses = ["R2"] + [c for c in (clauses_of(cases[0]) if len(cases) == 1 else []) if c != "R2"]
        failure = Failure(number, "death", clauses, message, cases, confirmed=confirmed)
        self._write(failure, evidence)

    # -- the summary ------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        cfg = self.config
        elapsed = time.monotonic() - self.started
        stats = self.executor.stats
        return {
            "tool": f"isight-conformance {__version__} fuzz",
            "command": cfg.command,
            "seed": self.seed,
            "rerun": f"add --seed {self.seed} (with --database none the campaign repeats exactly)",
            "target": str(cfg.target),
            "udp_target": str(cfg.udp_target) if cfg.udp_target else None,
            "profile": cfg.profile.to_dict(),
            "extension": cfg.extension,
            "database": cfg.database_label,
            "started": _dt.datetime.fromtimestamp(self.started_wall, _dt.timezone.utc).isoformat(timespec="seconds"),
            "duration_s": round(elapsed, 3),
            "examples": self.examples,
            "examples_per_s": round((self.examples + self.shrink_runs) / self.frames_s, 1) if self.frames_s else None,
            "shrink_runs": self.shrink_runs,
            "stateful": {"runs": self.stateful_runs, "steps": self.stateful_steps},
            "connections": stats.connections,
            "liveness_checks": stats.liveness_checks,
            "by_kind": dict(sorted(stats.by_kind.items())),
            "disabled_kinds": sorted(self.disabled),
            "stopped": self.stopped or None,
            "failures": [f.to_dict() for f in self.failures],
            "non_strict": [vars(o) | {"key": k} for k, o in self.non_strict.items()],
        }
