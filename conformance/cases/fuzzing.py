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

from conformance.fuzz.catalogue_campaign import FINDINGS, FRAMES_S, SESSION_S, judge_campaign, run_campaign
from conformance.suite import (
    CaseContext,
    Level,
    case,
)


@case("FUZZ-01", ["R1", "R2", "A1", "A3", "A5", "B3", "B4", "B5", "F5", "R6"], Level.MUST,
      "Two seconds of fuzzed frames (every strategy, each followed by a probe)",
      "no 0000 to malformed input (R1, A5, A3), A3's error where PROTOCOL.md names one (SHOULD), every valid "
      "request answered in order (A1), a fresh connection always answered (R2)", checks=FINDINGS)
def test_fuzz_frames(isight: CaseContext) -> None:
    judge_campaign(isight, run_campaign(isight, "FUZZ-01", FRAMES_S, stateful_share=0.0))


@case("FUZZ-02", ["S2", "S3", "S4", "S6", "A1", "R2", "E2", "E3"], Level.MUST,
      "One second of fuzzed sessions (cycles, streams, malformed input, reconnects)",
      "CycleOn 0000/0001 and CycleOff 0000/0002 as the cycle state allows (S2, S3), every pose and tolerance "
      "answered 0000 on either connection (S3, S4, S6), ProgIdx/result as E2/E3 say, the box alive after (R2)",
      checks=FINDINGS)
def test_fuzz_sessions(isight: CaseContext) -> None:
    judge_campaign(isight, run_campaign(isight, "FUZZ-02", SESSION_S, stateful_share=1.0))
