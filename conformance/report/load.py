"""Reading a summary.json back: for ``diff``, ``run --baseline`` and re-rendering a report.

:func:`load_summary` takes a summary.json or the report directory holding one and
raises :class:`SummaryError` (one line, no traceback) for a path that is missing,
unreadable, not JSON or not a summary. :func:`suite_of`, :func:`cases_of` and
:func:`root_causes_of` rebuild the data classes from it (a summary keeps no wire log,
latencies or details: the reports made from it show what summary.json holds).
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any

from ..model.verdicts import CaseResult, Level, RootCause, SuiteInfo, Verdict

SUMMARY_NAME = "summary.json"
MAX_SUMMARY_BYTES = 256 * 1024 * 1024  # a summary of 10,000 cases is a few MB


class SummaryError(ValueError):
    """A summary.json that cannot be used; the message is one line for the user."""


def summary_path(path: str | os.PathLike[str]) -> Path:
    """``path`` itself, or ``path/summary.json`` when it is a directory."""
    p = Path(path)
    return p / SUMMARY_NAME if p.is_dir() else p


def load_summary(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The parsed summary.json at ``path`` (a file or a report directory)."""
    p = summary_path(path)
    try:
        size = p.stat().st_size
        if size > MAX_SUMMARY_BYTES:
            raise SummaryError(f"{p}: {size} bytes, too large for a summary.json")
        raw = p.read_bytes()
    except FileNotFoundError:
        where = f"{path} holds no {SUMMARY_NAME}" if Path(path).is_dir() else f"{p}: no such file"
        raise SummaryError(where) from None
    except OSError as exc:
        raise SummaryError(f"{p}: cannot read it ({exc.strerror or exc})") from None
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SummaryError(f"{p}: not JSON ({exc})") from None
    problem = _shape_problem(doc)
    if problem:
        raise SummaryError(f"{p}: not an isight-conformance summary.json ({problem})")
    return doc


def _shape_problem(doc: Any) -> str | None:
    if not isinstance(doc, dict):
        return "the top level is not an object"
    if not isinstance(doc.get("suite"), dict) or not isinstance(doc.get("cases"), list):
        return "no 'suite' object and 'cases' list"
    verdicts = {v.value for v in Verdict}
    for i, case in enumerate(doc["cases"]):
        if not isinstance(case, dict) or not isinstance(case.get("id"), str):
            return f"case {i} has no id"
        if case.get("verdict") not in verdicts:
            return f"case {case['id']} has no known verdict"
        if not isinstance(case.get("clauses", []), list):
            return f"case {case['id']} has no clause list"
    if not isinstance(doc.get("root_causes", []), list):
        return "'root_causes' is not a list"
    return None


def suite_of(doc: dict[str, Any]) -> SuiteInfo:
    """The SuiteInfo a summary was written from (fields it lacks get their defaults)."""
    fields = {f.name for f in dataclasses.fields(SuiteInfo)}
    known = {k: v for k, v in doc["suite"].items() if k in fields}
    known.setdefault("version", "")
    known.setdefault("started", "")
    known.setdefault("duration_s", 0.0)
    known.setdefault("target", "")
    known.setdefault("profile", {})
    return SuiteInfo(**known)


def _level(value: Any) -> Level:
    try:
        return Level(value)
    except ValueError:
        return Level.MUST


def cases_of(doc: dict[str, Any]) -> list[CaseResult]:
    """The cases of a summary, as CaseResults (no wire log, latencies or details)."""
    out = []
    for c in doc["cases"]:
        out.append(CaseResult(
            id=c["id"], title=str(c.get("title", "")), clauses=tuple(str(x) for x in c.get("clauses", [])),
            level=_level(c.get("level")), verdict=Verdict(c["verdict"]),
            duration_s=float(c.get("duration_s") or 0.0), message=str(c.get("message") or ""),
            expected=str(c.get("expected") or ""),
            observed=str(c.get("observed") or ""), sent_hex=str(c.get("sent_hex") or ""),
            received_hex=str(c.get("received_hex") or ""), pcap=c.get("pcap"), root_cause=c.get("root_cause"),
            judged=tuple(str(x) for x in c.get("judged") or ()),
        ))
    return out


def root_causes_of(doc: dict[str, Any]) -> list[RootCause]:
    """The root causes of a summary, in the order written (the order to fix them)."""
    out = []
    for r in doc.get("root_causes", []):
        if not isinstance(r, dict) or "id" not in r:
            continue
        out.append(RootCause(
            id=str(r["id"]), clauses=tuple(str(x) for x in r.get("clauses", [])), title=str(r.get("title", "")),
            evidence=str(r.get("evidence", "")), cases=[str(x) for x in r.get("cases", [])],
            level=_level(r.get("level")), kind=str(r.get("kind", "")),
            confirmed=r.get("confirmed") if isinstance(r.get("confirmed"), bool) else None,
            diagnosis=r.get("diagnosis") if isinstance(r.get("diagnosis"), dict) else None,
        ))
    return out

