"""What a campaign does with a failing case: confirm it, let hypothesis shrink it, state it plainly, write it.

A failing case is confirmed on a fresh connection before hypothesis sees it (what a
box did with an earlier case on a reused connection must not be blamed on a later
one). A confirmed failure is raised to hypothesis (:class:`FuzzFailure`), which shrinks
it with every case isolated on its own connection; the shrunk case is then searched
for again with the strategy that states its clause most plainly (:meth:`Triage.rederive`),
and the minimal case is rerun once more on a fresh transcript: that run is the
evidence (vector file, pcap). Not shrunk: a hang (each shrink step would wait time_out)
and a failure that only happens on a reused connection.

Distinct failures are told apart by what failed (clause, rule, action): once one is
recorded its keys are :attr:`Triage.known`, and examples failing the same way no longer count.
"""

from __future__ import annotations

from collections.abc import Callable

from hypothesis import HealthCheck, Phase, Verbosity, given, seed, settings
from hypothesis.errors import Flaky

from .. import __version__
from ..harness.client import Silence
from ..harness.transcript import Transcript
from .config import CampaignConfig
from .executor import Executor, Result
from .failure_files import Failure, clauses_of, write_pcap, write_vectors
from .oracle import Finding
from .strategies import FuzzCase, Strategies

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


class Triage:
    """The distinct failures of one campaign, and the way each one is confirmed, shrunk and written.

    ``examples`` says how many examples the campaign has run (a failure records when it
    was found). The campaign's loop asks :meth:`new_failures`, :meth:`confirm` and
    :meth:`route`; while :attr:`shrinking` it hands every failing result to hypothesis.
    """

    def __init__(self, config: CampaignConfig, campaign_seed: int, strategies: Strategies, executor: Executor,
                 examples: Callable[[], int], clock: Callable[[], float] = lambda: 0.0) -> None:
        self.config = config
        self.clock = clock
        self.seed = campaign_seed
        self.strategies = strategies
        self.executor = executor
        self.examples = examples
        self.failures: list[Failure] = []
        self.known: set[str] = set()
        self.shrink_runs = 0  # cases run while shrinking or rederiving (outside the budget)
        self.shrinking = False
        self.pending: Result | None = None  # the confirmed failure hypothesis is shrinking
        self.known_before_shrink: set[str] = set()

    @property
    def next_number(self) -> int:
        return len(self.failures) + 1

    def new_failures(self, result: Result) -> list[Finding]:
        return [f for f in result.judgement.failures if f.key not in self.known]

    # -- before hypothesis -----------------------------------------------------------------
    def confirm(self, case: FuzzCase) -> Result:
        """The case again, on a fresh connection, watched for late answers."""
        ex = self.executor
        ex.isolate = ex.settle = True
        try:
            return ex.run(case, f"confirming on a fresh connection: {case.describe()}")
        finally:
            ex.isolate = ex.settle = False
            ex.drop_connection()

    def route(self, result: Result, confirmed: Result, keys: set[str], history: list[FuzzCase]) -> Result | None:
        """Where a failure goes once its confirmation ran: the result to raise to hypothesis, or None.

        Not confirmed: written as a failure of the reused connection. A hang: written
        unshrunk. Otherwise hypothesis shrinks it, every case on its own connection."""
        if not self.new_failures(confirmed):
            self.record_context(result, history)
            self.known |= keys
            return None
        if isinstance(confirmed.end, Silence):  # a hang: shrinking would wait time_out per step
            self.record(confirmed, "oracle", shrunk=False)
            self.known |= keys
            return None
        self.known_before_shrink = keys
        self.pending = confirmed
        self.shrinking = True
        self.executor.isolate = True
        return confirmed

    def settle(self, result: Result, confirmed: Result, keys: set[str], history: list[FuzzCase]) -> None:
        """A failure found outside hypothesis (a case of the boundary schedule): hypothesis cannot shrink it, so
        the plain strategy of its clause looks for it again (:meth:`rederive`); else it is written as it is."""
        if not self.new_failures(confirmed):
            self.record_context(result, history)
        else:
            plainer = self.rederive(confirmed)
            self.record(plainer or confirmed, "oracle", shrunk=plainer is not None)
        self.known |= keys

    # -- after hypothesis ------------------------------------------------------------------
    def record_shrunk(self, result: Result) -> None:
        plainer = self.rederive(result)
        # only what the recorded failure shows becomes known: hypothesis may have shrunk one failure into
        # another (the same raise site), and the first must then still count when it comes again
        self.record(plainer or result, "oracle", shrunk=True)

    def record_pending(self) -> None:
        """Hypothesis could not replay the failure it was shrinking: it is written as found, unshrunk."""
        if self.pending is not None:
            self.record(self.pending, "oracle", shrunk=False)
            self.known |= self.known_before_shrink

    def end_shrink(self) -> None:
        self.pending = None
        self.shrinking = False
        self.executor.isolate = self.executor.settle = False

    def rederive(self, result: Result) -> Result | None:
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

        def plain(case: FuzzCase) -> None:
            self.shrink_runs += 1
            r = ex.run(case, f"the same failure from the {category} strategy? {case.describe()}")
            if {f.key for f in r.judgement.failures} & keys:
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

    # -- writing -----------------------------------------------------------------------------
    def evidence_run(self, case: FuzzCase, number: int) -> tuple[Result, Transcript]:
        """The case once more on a fresh connection and transcript of its own: the evidence."""
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

    def record(self, result: Result, kind: str, shrunk: bool) -> Failure:
        number = self.next_number
        case = result.case
        evidence, tr = self.evidence_run(case, number)
        reproduced = bool(evidence.judgement.failures)
        best = evidence if reproduced else result
        first = best.judgement.failures[0] if best.judgement.failures else result.judgement.failures[0]
        message = f"{first.requirement}; the box {best.observed()}"
        if not reproduced:
            message += " (the evidence run on a fresh connection did not reproduce it)"
        failure = Failure(number, kind, clauses_of(case, [f.clause for f in best.judgement.failures]), message,
                          [case], shrunk=shrunk, confirmed=reproduced, keys=[f.key for f in best.judgement.failures])
        self.known |= {f.key for f in result.judgement.failures} | {f.key for f in evidence.judgement.failures}
        return self.write(failure, tr)

    def record_context(self, result: Result, history: list[FuzzCase]) -> None:
        first = result.judgement.failures[0]
        message = (f"{first.requirement}; the box {result.observed()} — only after the cases before it on the same "
                   "connection (on a fresh connection the last case passes)")
        failure = Failure(self.next_number, "context", clauses_of(result.case, [first.clause]), message,
                          history or [result.case], confirmed=False, keys=[first.key])
        self.write(failure, self.executor.transcript)

    def write(self, failure: Failure, transcript: Transcript) -> Failure:
        """The failure's vector file and pcap, in the campaign's list, and a line in its log."""
        cfg = self.config
        name = f"{cfg.name}-{failure.number:03d}"
        desc = (f"isight-conformance {__version__} fuzz: failure {failure.number} against {cfg.target} "
                f"(seed {self.seed}, profile {cfg.profile.describe()})")
        failure.found_after = self.examples()
        failure.found_s = self.clock()
        if cfg.report_dir is not None:
            failure.vector = write_vectors(cfg.report_dir / f"{name}.json", failure, cfg.profile, desc)
        if cfg.capture != "off" and cfg.pcap_dir is not None:
            failure.pcap = write_pcap(transcript, cfg.pcap_dir / f"{name}.pcapng")
        self.failures.append(failure)
        cfg.log(f"fuzz: FAIL {failure.number} [{', '.join(failure.clauses)}] {failure.message}\n"
                f"      bytes: {failure.hex}" + (f"\n      vector: {failure.vector}" if failure.vector else "")
                + (f"\n      pcap: {failure.pcap}" if failure.pcap else "")
                + (f"\n      box: {failure.last_words.summary()}" if failure.last_words is not None else ""))
        return failure


__all__ = ["PLAIN", "REDERIVE_EXAMPLES", "FuzzFailure", "Triage"]
