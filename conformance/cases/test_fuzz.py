"""Fuzz campaigns as conformance cases: short, bounded, deterministic (a fixed seed, no database).

* FUZZ-01: two seconds of frames from every strategy of :mod:`conformance.fuzz.strategies`
  (valid requests, each header field broken, shapes, indexes, float edge values,
  truncation, trailing bytes, check fields, oversized headers, byte-level mutations,
  garbage; UDP datagrams when there is a UDP target), each followed by a probe and
  judged by the fuzz oracle, liveness on a fresh connection every 64 cases and after
  every anomaly (R2).
* FUZZ-02: one second of the session state machine (:mod:`conformance.fuzz.session_runner`):
  cycles, poses on a stream connection, tolerances, ProgIdx/result when the box has E,
  malformed frames and reconnects, interleaved.

A failure is shrunk by hypothesis and the case FAILs with the shrunk bytes; with
``--report-dir`` the vector file (replay it with ``isight-conformance replay``) goes to
``<report-dir>/fuzz/``, with ``--pcap-dir`` the failing example's own pcap next to the
case's. For longer campaigns use ``isight-conformance fuzz`` (docs/FUZZING.md).
"""

from __future__ import annotations

from conformance.fuzz.campaign import Campaign, CampaignConfig, CampaignResult
from conformance.suite.context import CaseContext
from conformance.suite.record import Requirement, case
from conformance.suite.signature import Signature
from conformance.suite.verdicts import Level

FRAMES_S = 2.0
SESSION_S = 1.0


def _campaign(isight: CaseContext, name: str, seconds: float, stateful_share: float) -> CampaignResult:
    settings = isight.settings
    extension = isight.session.detect_extension(isight.transcript)
    isight.needs_liveness = True
    config = CampaignConfig(
        target=isight.target, profile=isight.profile, udp_target=isight.session.udp_target(),
        stream_target=isight.session.stream_target(), seed=settings.seed, duration_s=seconds, stateful_share=stateful_share,
        report_dir=settings.report_dir / "fuzz" if settings.report_dir is not None else None,
        pcap_dir=settings.pcap_dir, capture="failures" if settings.pcap_dir is not None else "off",
        database=None, extension=extension, settle_s=settings.settle_s, log=lambda line: None,
        transcript=isight.transcript, name=f"{name}-failure",
    )
    result = Campaign(config).run()
    summary = result.to_dict()
    isight.details["fuzz"] = {k: summary[k] for k in ("seed", "examples", "examples_per_s", "stateful", "connections",
                                                      "liveness_checks", "by_kind", "stopped", "coverage",
                                                      "failures", "non_strict")}
    return result


#: what a campaign's failures judge: the words and the clauses come from the oracle's findings
FINDINGS = {"failure": Requirement((), "{finding}", judged_from="clauses"),
            "non-strict": Requirement((), "{finding}", level=Level.SHOULD, judged_from="clauses")}


def _judge(isight: CaseContext, result: CampaignResult) -> None:
    failures = result.failures
    if failures:
        first = failures[0]
        more = f" (and {len(failures) - 1} more distinct failures)" if len(failures) > 1 else ""
        where = f"; vector {first.vector}" if first.vector else ""
        sent = first.cases[0].wire if first.cases else b""
        clause = first.clauses[0] if first.clauses else "R1"
        # a malformed answer found by fuzzing groups with the cases that found the same malformation
        signature = Signature.fuzz(clause, malformed_answer=first.malformed_answer)
        raise isight.broken("failure", expected="no failure: every example answered as PROTOCOL.md allows",
                            observed=f"fuzz failure ({first.kind}, seed {result.seed}){where}", sent=sent,
                            signature=signature, finding=f"{', '.join(first.clauses)}: {first.message}{more}",
                            clauses=tuple(first.clauses))
    if result.non_strict:
        obs = result.non_strict[0]
        raise isight.broken("non-strict", expected="every SHOULD of PROTOCOL.md kept",
                            observed=f"the box {obs.observed} (×{obs.count})", sent=bytes.fromhex(obs.hex),
                            signature=Signature.fuzz(obs.clause, key=obs.key), finding=f"[{obs.clause}] {obs.requirement}",
                            clauses=(obs.clause,))


@case("FUZZ-01", ["R1", "R2", "A1", "A3", "A5", "B3", "B4", "B5", "F5", "R6"], Level.MUST,
      "Two seconds of fuzzed frames (every strategy, each followed by a probe)",
      "no 0000 to malformed input (R1, A5, A3), A3's error where PROTOCOL.md names one (SHOULD), every valid "
      "request answered in order (A1), a fresh connection always answered (R2)", checks=FINDINGS)
def test_fuzz_frames(isight: CaseContext) -> None:
    _judge(isight, _campaign(isight, "FUZZ-01", FRAMES_S, stateful_share=0.0))


@case("FUZZ-02", ["S2", "S3", "S4", "S6", "A1", "R2", "E2", "E3"], Level.MUST,
      "One second of fuzzed sessions (cycles, streams, malformed input, reconnects)",
      "CycleOn 0000/0001 and CycleOff 0000/0002 as the cycle state allows (S2, S3), every pose and tolerance "
      "answered 0000 on either connection (S3, S4, S6), ProgIdx/result as E2/E3 say, the box alive after (R2)",
      checks=FINDINGS)
def test_fuzz_sessions(isight: CaseContext) -> None:
    _judge(isight, _campaign(isight, "FUZZ-02", SESSION_S, stateful_share=1.0))
