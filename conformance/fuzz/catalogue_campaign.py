"""The FUZZ cases' campaign (conformance/cases/fuzzing.py): a short, bounded campaign run for a case, and its verdict."""

from __future__ import annotations

from ..runtime.box_stall import STALL
from ..suite import CaseContext, Level, Requirement, Signature
from . import second_look
from .campaign import Campaign, CampaignConfig, CampaignResult

FRAMES_S = 2.0
SESSION_S = 1.0


def run_campaign(isight: CaseContext, name: str, seconds: float, stateful_share: float) -> CampaignResult:
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


def judge_campaign(isight: CaseContext, result: CampaignResult) -> None:
    failures = result.failures
    stalls = second_look.take((isight.target.host, isight.target.port))  # box-wide: never the bytes' verdict
    if stalls:
        isight.details["box_stall"] = [s.to_dict() for s in stalls]
    if stalls and not failures:
        raise isight.broken("failure", expected="every connection answered within time_out", observed=stalls[0].describe(),
                            sent=b"", signature=STALL, finding=f"T1/S4: {stalls[0].describe()}",
                            clauses=("T1", "S4"))
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
