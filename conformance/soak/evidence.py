"""The soak's evidence: ``soak.json`` (every window and verdict), and the same ``summary.json``
and ``junit.xml`` as ``run`` (one case per clause judged, ``SOAK-T2`` and so on).

Every file is written atomically. A checkpoint rewrites them all at the end of every window, so
a soak killed after six hours keeps six hours of windows and the verdicts they gave (marked
incomplete); the final write marks them complete. Once the final write is done, a checkpoint
still running in its thread is ignored (the lock and :attr:`EvidenceWriter.final`).
"""

from __future__ import annotations

import datetime as _dt
import json
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .. import __version__
from ..model.verdicts import CaseResult, Level, SuiteInfo
from ..report.junit import write_junit
from ..report.summary import atomic_write_bytes, write_summary
from .verdicts import Judged

FORMAT = "isight-soak/1"


def soak_cases(judged: Judged, duration_s: float) -> list[CaseResult]:
    """One case per clause the soak judged, as ``run`` reports cases."""
    out = []
    for v in judged.verdicts:
        out.append(CaseResult(
            id=f"SOAK-{v.clause}", title=v.title, clauses=(v.clause,), level=Level.MUST, verdict=v.verdict,
            duration_s=duration_s, message=v.message, requirement=v.title, observed=v.message,
            expected="flat over the soak: no session failing, no trend beyond noise",
            details={"windows": v.windows, **v.details}, judged=(v.clause,) if v.verdict.failing else (),
        ))
    return out


class EvidenceWriter:
    """Writes the soak's files into ``report_dir``; ``build()`` is supplied by the command (the document)."""

    def __init__(self, report_dir: Path, build: Callable[[bool], tuple[dict[str, Any], Judged]], command: str,
                 html: Callable[[dict[str, Any], Path], None] | None = None) -> None:
        self.report_dir = report_dir
        self.build = build
        self.command = command
        self.html = html
        self.final = False
        self.failures = 0
        self._lock = threading.Lock()
        self.started = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")

    def checkpoint(self, *_: object) -> None:
        self.write(final=False)

    def write(self, final: bool) -> dict[str, Any] | None:
        with self._lock:
            if self.final:
                return None
            doc, judged = self.build(final)
            try:
                self._write(doc, judged)
            except OSError as exc:
                self.failures += 1
                print(f"isight-conformance soak: cannot write the evidence into {self.report_dir}: {exc}",
                      file=sys.stderr)
                return doc
            self.final = final
            return doc

    def _write(self, doc: dict[str, Any], judged: Judged) -> None:
        text = json.dumps(doc, indent=1, ensure_ascii=False, default=str) + "\n"
        atomic_write_bytes(self.report_dir / "soak.json", text.encode("utf-8", "backslashreplace"))
        cases = soak_cases(judged, doc["elapsed_s"])
        suite = SuiteInfo(version=__version__, started=self.started, duration_s=doc["elapsed_s"],
                          target=doc["target"], profile=doc["profile"], extension=doc["extension"],
                          command=self.command, role="box", complete=doc["complete"], cases_total=len(cases))
        write_summary(self.report_dir / "summary.json", suite, cases)
        write_junit(self.report_dir / "junit.xml", suite, cases)
        if self.html is not None:
            self.html(doc, self.report_dir / "report.html")


__all__ = ["FORMAT", "EvidenceWriter", "soak_cases"]
