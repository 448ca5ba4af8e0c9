"""Helpers for the fleet tests: box runs whose reports are written by the real report writers."""

from __future__ import annotations

from pathlib import Path

from conformance.fleet.children import BoxRun
from conformance.fleet.spec import BoxSpec
from conformance.model.verdicts import CaseResult, Level, RootCause, SuiteInfo, Verdict
from conformance.report.summary import write_summary


def case(case_id: str, verdict: Verdict, root_cause: str | None = None) -> CaseResult:
    return CaseResult(id=case_id, title=f"case {case_id}", clauses=(case_id.split("-")[0],), level=Level.MUST,
                      verdict=verdict, root_cause=root_cause)


def box_run(tmp_path: Path, name: str, *, status: str = "finished", exit_code: int | None = 0,
            cases: list[CaseResult] | None = None, expected: tuple[str, ...] | None = None,
            root_causes: tuple[RootCause, ...] = (), log: str = "", target: str | None = None,
            complete: bool = True) -> BoxRun:
    """A BoxRun as the runner leaves it, with its summary.json (if ``cases``) and run.log on disk."""
    settings = {"target": (target,)} if target else {}
    spec = BoxSpec(name=name, line=1, settings=settings, expected_failures=expected)
    run = BoxRun(spec, tmp_path / name, tmp_path / name / "pcaps", status=status, exit_code=exit_code,
                 duration_s=None if status == "not run" else 12.5, command=["isight-conformance", "run"])
    if status == "not run":
        return run
    run.report_dir.mkdir(parents=True, exist_ok=True)
    run.log.write_text(log, encoding="utf-8")
    if cases is not None:
        suite = SuiteInfo(version="0", started="2024-06-01T10:15:00+00:00", duration_s=12.5,
                          target=target or "bundled reference box at 127.0.0.1:40000", profile={},
                          complete=complete, cases_total=len(cases))
        write_summary(run.report_dir / "summary.json", suite, cases, root_causes)
        (run.report_dir / "report.html").write_text("<html></html>")
        run.pcap_dir.mkdir(parents=True, exist_ok=True)
    return run
