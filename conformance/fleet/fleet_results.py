"""What each box of a fleet run did (from its summary.json and exit code), and fleet.json.

A box's entry in fleet.json::

    {"name", "line", "target", "status", "passed", "overall", "overall_state", "totals",
     "failing", "expected_failures", "unexpected_failures", "unexpectedly_passing",
     "root_causes", "report", "summary", "junit", "pcaps", "log", "exit_code", "duration_s",
     "message", "command"}

``status`` is one of :data:`STATUSES`. Paths are relative to the fleet directory (where
fleet.json and fleet.html are). ``passed`` is what the box contributes to the fleet's
exit status: its ``run`` exited 0 (no FAIL/ERROR, or exactly its expected failures).
"""

from __future__ import annotations

import dataclasses
import json
import os
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .. import __version__
from ..i18n import _, current
from ..model.verdicts import CaseResult, Level, SuiteInfo, Verdict
from ..report.summary import atomic_write_bytes, one_line, overall_line, overall_state
from .children import BoxRun

FORMAT = "isight-fleet-1"
#: box statuses, worst first
STATUSES = ("error", "fails", "interrupted", "not run", "incomplete", "unjudged", "expected failures", "conforms")


def read_summary(path: Path) -> dict[str, Any] | None:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) and isinstance(doc.get("cases"), list) else None


def _cases(doc: dict[str, Any]) -> list[CaseResult]:
    out = []
    for c in doc["cases"]:
        try:
            out.append(CaseResult(id=str(c["id"]), title=str(c.get("title", "")), clauses=tuple(c.get("clauses", ())),
                                  level=Level(c.get("level", "MUST")), verdict=Verdict(c["verdict"])))
        except (KeyError, ValueError, TypeError):
            continue
    return out


def _suite(doc: dict[str, Any]) -> SuiteInfo | None:
    raw = doc.get("suite")
    if not isinstance(raw, dict):
        return None
    names = {f.name for f in dataclasses.fields(SuiteInfo)}
    try:
        return SuiteInfo(**{k: v for k, v in raw.items() if k in names})
    except TypeError:
        return None


def last_error(log: Path, limit: int = 300) -> str:
    """The last line the child wrote that says what went wrong (or its last line)."""
    try:
        with open(log, "rb") as fh:
            fh.seek(max(0, os.path.getsize(log) - 16384))
            lines = [ln.strip() for ln in fh.read().decode("utf-8", "replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    ours = [ln.removeprefix("isight-conformance run: ") for ln in lines if ln.startswith("isight-conformance")]
    return one_line((ours or lines or [""])[-1], limit)


def _rel(path: Path, fleet_dir: Path) -> str:
    return Path(os.path.relpath(os.path.abspath(path), os.path.abspath(fleet_dir))).as_posix()


def box_entry(run: BoxRun, fleet_dir: Path) -> dict[str, Any]:
    spec = run.spec
    entry: dict[str, Any] = {
        "name": spec.name, "line": spec.line, "target": spec.target or "bundled reference box",
        "status": run.status, "passed": False, "overall": "", "overall_state": "", "totals": None,
        "failing": [], "expected_failures": list(spec.expected_failures) if spec.expected_failures is not None else None,
        "unexpected_failures": [], "unexpectedly_passing": [], "root_causes": [],
        "report": None, "summary": None, "junit": None, "pcaps": None, "log": None,
        "exit_code": run.exit_code, "duration_s": round(run.duration_s, 3) if run.duration_s is not None else None,
        "message": "", "command": shlex.join(run.command) if run.command else "",
    }
    if run.status == "not run":
        entry["overall"] = _("NOT RUN: the fleet run was stopped before this box started")
        return entry
    entry["log"] = _rel(run.log, fleet_dir) if run.log.is_file() else None
    doc = read_summary(run.report_dir / "summary.json")
    if doc is not None:
        cases, suite = _cases(doc), _suite(doc)
        failing = sorted(c.id for c in cases if c.verdict.failing)
        expected = set(spec.expected_failures or ())
        entry.update(
            target=suite.target if suite is not None and suite.target else entry["target"],
            overall=overall_line(cases, suite), overall_state=overall_state(cases, suite),
            totals=doc.get("totals"), failing=failing,
            root_causes=doc.get("root_causes") if isinstance(doc.get("root_causes"), list) else [],
            summary=_rel(run.report_dir / "summary.json", fleet_dir),
        )
        if spec.expected_failures is not None:
            entry["unexpected_failures"] = sorted(set(failing) - expected)
            entry["unexpectedly_passing"] = sorted(expected - set(failing))
        for key, name in (("report", "report.html"), ("junit", "junit.xml")):
            if (run.report_dir / name).is_file():
                entry[key] = _rel(run.report_dir / name, fleet_dir)
        if run.pcap_dir.is_dir():
            entry["pcaps"] = _rel(run.pcap_dir, fleet_dir)
    if run.status == "interrupted":  # whatever its summary says, this box's run was cut short
        entry["overall"] = (_("INTERRUPTED: the fleet run was stopped after {n} cases of this box").format(
            n=len(doc["cases"])) if doc is not None else
            _("INTERRUPTED: the fleet run was stopped before this box wrote a report"))
        entry["overall_state"] = "incomplete"
        return entry
    if doc is not None and run.exit_code == 3:  # the box's run was cut short on its own (a signal to it)
        entry["status"] = entry["overall_state"] = "incomplete"
        return entry
    if doc is None or run.exit_code not in (0, 1):
        entry["status"] = "error"
        entry["message"] = last_error(run.log) or _("run exited with status {code} and wrote no summary").format(
            code=run.exit_code)
        entry["overall"] = entry["overall"] or _("NOT JUDGED: the box's run ended with exit status {code}").format(
            code=run.exit_code)
        return entry
    entry["passed"] = run.exit_code == 0
    if run.exit_code == 1:
        entry["status"] = "fails"
        entry["message"] = last_error(run.log) if spec.expected_failures is not None else ""
    elif entry["failing"]:
        entry["status"] = "expected failures"
    else:
        entry["status"] = {"conforms": "conforms", "incomplete": "incomplete"}.get(entry["overall_state"], "unjudged")
    return entry


def fleet_document(runs: Sequence[BoxRun], fleet_dir: Path, *, fleet_file: Path, jobs: int, started: str,
                   duration_s: float, command: str, stopped: str | None) -> dict[str, Any]:
    boxes = [box_entry(run, fleet_dir) for run in runs]
    complete = stopped is None and all(b["status"] not in ("not run", "interrupted") for b in boxes)
    passed = complete and all(b["passed"] for b in boxes)
    counts = {s: sum(1 for b in boxes if b["status"] == s) for s in STATUSES}
    return {
        "format": FORMAT, "version": __version__, "started": started, "duration_s": round(duration_s, 3),
        "fleet_file": str(fleet_file), "report_dir": str(fleet_dir), "jobs": jobs, "command": command,
        "complete": complete, "stopped": stopped, "passed": passed, "exit_code": 0 if passed else 1,
        "lang": current(),  # the language of the "overall" lines; every other value is machine-read English
        "overall": overall_fleet_line(boxes, complete), "counts": {s: n for s, n in counts.items() if n},
        "boxes": boxes,
    }


def overall_fleet_line(boxes: Sequence[dict[str, Any]], complete: bool) -> str:
    n = len(boxes)
    ok = sum(1 for b in boxes if b["passed"])
    if not complete:
        done = sum(1 for b in boxes if b["status"] not in ("not run", "interrupted"))
        return _("INCOMPLETE: the run was stopped; {done} of {n} boxes finished, {ok} of them passed").format(
            done=done, n=n, ok=ok)
    if ok == n:
        return _("FLEET PASSES: all {n} boxes conform (or fail exactly their expected failures)").format(n=n)
    return _("FLEET FAILS: {bad} of {n} boxes do not pass").format(bad=n - ok, n=n)


def write_fleet_json(path: Path, doc: dict[str, Any]) -> Path:
    text = json.dumps(doc, indent=2, ensure_ascii=False) + "\n"
    return atomic_write_bytes(path, text.encode("utf-8", "backslashreplace"))
