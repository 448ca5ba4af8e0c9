"""Fuzz campaigns: hypothesis generates and shrinks, the executor sends, the oracle judges.

The campaign runs hypothesis in *chunks*: each chunk is one ``@given`` run of
``chunk_examples`` examples, with its own seed derived from the campaign's seed (so
``--seed`` makes the whole campaign repeat) and the same database key (so a failure
found once is replayed first next time). One hypothesis example is a *batch*: a list
of up to ``batch`` fuzz cases, run one after the other on a reused connection;
hypothesis pays its per-example overhead once per batch, and shrinks a failing batch
down to the one case that fails and that case down to its simplest frame. Between
chunks the campaign checks its budget (``max_examples`` cases or ``duration_s``); what
is left of it after the frames (``stateful_share``) goes to the session state machine
(:mod:`.stateful`), whose result the campaign adds to its own.

This module is the loop. A failing case is confirmed, shrunk, stated plainly and
written by :mod:`.triage`; a box that *dies* (R2) stops the campaign, and
:mod:`.death` finds which input killed it.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

from hypothesis import HealthCheck, Phase, Verbosity, given, settings
from hypothesis import strategies as st
from hypothesis.errors import Flaky

from .. import __version__
from ..evidence.pcap import PcapRecorder
from ..harness.client import Silence
from ..harness.transcript import Transcript
from ..options import profile_flags
from ..suite.verdicts import Verdict
from .config import CampaignConfig, new_seed
from .death import STOPPED, Seen, find_killer
from .evidence import Failure, write_summary
from .executor import Executor, Result, alive
from .stateful import run_stateful
from .strategies import FuzzCase, Strategies
from .triage import FuzzFailure, Triage

#: Cases per campaign pcap file when every case is recorded (``capture="all"``).
SEGMENT_CASES = 20_000
#: Events kept in memory per campaign transcript (the pcap has them all).
KEEP_EVENTS = 20_000


@dataclass
class Observation:
    """A SHOULD the box broke (NON-STRICT), first seen on ``hex``."""

    clause: str
    requirement: str
    observed: str
    kind: str
    hex: str
    count: int = 1


class Campaign:
    """``Campaign(config).run()``: the summary (also written to ``fuzz-summary.json``)."""

    def __init__(self, config: CampaignConfig) -> None:
        cfg = self.config = config
        self.seed = cfg.seed if cfg.seed is not None else new_seed()
        self.examples = 0
        self.non_strict: dict[str, Observation] = {}
        self.stopped = ""
        self.strategies = Strategies(cfg.profile, cfg.extension, udp=cfg.udp_target is not None)
        self.cases = self.strategies.cases(cfg.categories)
        self.disabled: set[str] = set()
        self.window: list[Seen] = []  # cases since the last good liveness check
        self.history: deque[FuzzCase] = deque(maxlen=16)  # cases on the current reused connection
        self.started = time.monotonic()
        self.started_wall = time.time()
        self.frames_s = 0.0
        self.stateful_steps = 0
        self.stateful_runs = 0
        self.stateful_started = 0.0
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
        self.triage = Triage(cfg, self.seed, self.strategies, self.executor, lambda: self.examples)
        self.digest = f"isight-fuzz/frames/{sorted(cfg.profile.to_dict().items())}/{cfg.extension}/" \
                      f"{cfg.udp_target is not None}/{cfg.categories}".encode()

    @property
    def failures(self) -> list[Failure]:
        return self.triage.failures

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

    def stateful_left(self, steps: int) -> bool:
        """May the session state machine run another step, ``steps`` steps into its share?"""
        cfg = self.config
        if self.stopped or len(self.failures) >= cfg.max_failures:
            return False
        if cfg.max_examples is not None and steps >= max(1, cfg.max_examples - (self.frames_budget or 0)):
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
                self._run_stateful()
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

    def _run_stateful(self) -> None:
        self.stateful_started = time.monotonic()
        result = run_stateful(self.config, self.strategies, self.seed, self.stateful_left, self.triage.next_number)
        self.stateful_runs += result.runs
        self.stateful_steps += result.steps
        self.failures.extend(result.failures)

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
        """Run a batch; the result of a confirmed failure to raise to hypothesis, else None."""
        ex, triage = self.executor, self.triage
        for case in batch:
            if self.stopped or (not triage.shrinking and not self.budget_left()):
                return None
            if case.kind in self.disabled:
                continue
            result = ex.run(case)
            self._segment_cases += 1
            if triage.shrinking:
                triage.shrink_runs += 1
            else:
                self.examples += 1
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
            if not failing:
                if result.anomaly:
                    self.history.clear()
                continue
            if triage.shrinking:
                return result
            history = list(self.history)  # the cases on this connection, before the confirmation run clears it
            confirmed = triage.confirm(case)
            self.history.clear()
            if confirmed.liveness is not None and not alive(confirmed.liveness):
                self.window.append(Seen(case, confirmed))
                self._on_death()
                return None
            raised = triage.route(result, confirmed, {f.key for f in failing}, history)
            if raised is not None:
                return raised
        return None

    def _on_death(self) -> None:
        window, self.window = self.window, []
        self.stopped = STOPPED
        failure, evidence = find_killer(self.config, window, self.executor, self.triage.next_number)
        self.triage.write(failure, evidence if evidence is not None else self.transcript)

    def _observe(self, case: FuzzCase, result: Result) -> None:
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
        rate = (self.examples + self.triage.shrink_runs) / max(1e-9, now - self.started)
        self.config.log(f"fuzz: {self.examples:,} examples ({rate:,.0f}/s), {len(self.failures)} failures, "
                        f"{len(self.non_strict)} kinds of NON-STRICT")

    # -- the summary ------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        cfg = self.config
        elapsed = time.monotonic() - self.started
        stats = self.executor.stats
        shrink_runs = self.triage.shrink_runs
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
            "examples_per_s": round((self.examples + shrink_runs) / self.frames_s, 1) if self.frames_s else None,
            "shrink_runs": shrink_runs,
            "stateful": {"runs": self.stateful_runs, "steps": self.stateful_steps},
            "connections": stats.connections,
            "liveness_checks": stats.liveness_checks,
            "by_kind": dict(sorted(stats.by_kind.items())),
            "disabled_kinds": sorted(self.disabled),
            "stopped": self.stopped or None,
            "failures": [f.to_dict() for f in self.failures],
            "non_strict": [vars(o) | {"key": k} for k, o in self.non_strict.items()],
        }


__all__ = ["KEEP_EVENTS", "SEGMENT_CASES", "Campaign", "CampaignConfig", "Observation"]
