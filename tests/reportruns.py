"""Realistic runs for the report's print tests and ``benchmarks/bench_report_print.py``,
and printing an HTML file to PDF with headless Chromium.

The runs are shaped like real ones (``isight-conformance run`` against the reference box
gives 275 cases: 247 PASS, 17 INFORMATIONAL, 11 SKIP; wire logs of a few lines up to
2,000; latency series on the timing cases). :func:`systematic_defect` perturbs a run the
way a box with one systematic defect does (every answer malformed): ~150 FAIL cases under
one root cause, ~60 NON-STRICT, some INCONCLUSIVE, each with the evidence such a case
carries (hex, expected/observed text, a wire log).
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict, WireLine

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "chromium", "chromium-browser",
                       "google-chrome", "google-chrome-stable")
PRINT_TIMEOUT_S = 240

FAMILY_CLAUSES = {
    "F": ("F1", "F2", "F3", "F5"), "B": ("B1", "B3", "B5"), "A": ("A1", "A2", "A3", "A5"), "S": ("S1", "S3", "S6"),
    "T": ("T1", "T2"), "R": ("R1", "R3", "R4", "R6"), "E": ("E1", "E2", "E4"),
}
POSE = "fefe000101230101001900" + "00" + "42c80000" * 6 + "0000"
#: requirements a systematic defect breaks: 8 kinds x 9 wordings, about as many distinct findings as a real run has
KINDS = ("NONE", "CycleOn", "CycleOff", "POSE", "REGISTER_POSE", "TOLERANCE", "ProgIdx", "result request")
WORDINGS = (
    "a well-formed {k} request is answered with type 10 and the action echoed",
    "a {k} request with a gap in its block indexes SHOULD be answered with its action's error",
    "a {k} request with a wrong block length MUST NOT be answered 0000",
    "a {k} request split into pieces is answered like the whole frame",
    "several {k} requests in one segment are each answered, in order",
    "a {k} request after garbage is answered once the box resynchronised",
    "a {k} request on a fresh connection is answered within time_out",
    "a {k} request with a wrong transfer type is not a request and MUST NOT be answered 0000",
    "the {k} request of a golden vector is answered as the vector says",
)
ANSWER = "fefe000110230000000000000000"


def chromium() -> str | None:
    """The Chromium binary, or None when none is installed."""
    for name in CHROMIUM_CANDIDATES:
        found = shutil.which(name)
        if found:
            return found
    return None


def pdf_pages(pdf: bytes) -> int:
    """The number of pages of a PDF: its ``/Type /Page`` objects, or the page tree's
    ``/Count`` when the objects are compressed."""
    pages = len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", pdf))
    counts = [int(n) for n in re.findall(rb"/Type\s*/Pages\b[^>]*?/Count\s+(\d+)", pdf, re.S)]
    counts += [int(n) for n in re.findall(rb"/Count\s+(\d+)[^>]*?/Type\s*/Pages\b", pdf, re.S)]
    return max([pages, *counts])


def print_to_pdf(html: Path, pdf: Path, binary: str | None = None) -> int:
    """Print ``html`` to ``pdf`` (A4, the report's own @page rules) with headless
    Chromium; returns the page count. Raises RuntimeError when Chromium fails."""
    binary = binary or chromium()
    if binary is None:
        raise RuntimeError("no chromium binary found")
    with tempfile.TemporaryDirectory(prefix="isight-chromium-") as profile:
        cmd = [binary, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={profile}",
               f"--print-to-pdf={pdf}", html.resolve().as_uri()]
        done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=PRINT_TIMEOUT_S,
                              env={**os.environ, "HOME": profile})
    if not pdf.is_file() or pdf.stat().st_size == 0:
        raise RuntimeError(f"chromium wrote no PDF (exit {done.returncode}): {done.stderr.decode(errors='replace')[-300:]}")
    return pdf_pages(pdf.read_bytes())


def _wire(n: int, case_no: int) -> list[WireLine]:
    lines = [WireLine(0.0, 1, "·", "connect", "", f"connected in 0.1 ms (tcp 127.0.0.1:{40000 + case_no} → 127.0.0.1:9004)")]
    for i in range(n - 1):
        if i % 2 == 0:
            lines.append(WireLine(i * 0.8, 1, "→", "send", POSE, f"pose #{i // 2}: x=100.0 y=100.0 z=100.0 w=100.0 p=100.0 r=100.0"))
        else:
            lines.append(WireLine(i * 0.8 + 0.3, 1, "←", "recv", ANSWER, "box→robot POSE err=0x0000 (OK)"))
    return lines


def conforming_run(n: int = 275) -> list[CaseResult]:
    """A run of a conforming box: 90 % PASS, 6 % INFORMATIONAL, 4 % SKIP."""
    cases = []
    families = list(FAMILY_CLAUSES)
    for i in range(n):
        fam = families[i % len(families)]
        clauses = FAMILY_CLAUSES[fam][: 1 + i % 3]
        verdict = Verdict.SKIP if i % 25 == 7 else Verdict.INFORMATIONAL if i % 16 == 3 else Verdict.PASS
        wire_n = 2001 if i % 60 == 11 else 120 if i % 9 == 0 else 8 + i % 15
        cases.append(CaseResult(
            f"{fam}{1 + i % 5}-{i:02d}[variant-{i % 13}]", f"Case {i}: a request of kind {i % 13} is answered in order",
            clauses, Level.MAY if verdict is Verdict.INFORMATIONAL else Level.MUST, verdict, 0.05 + (i % 7) * 0.1,
            message="" if verdict is Verdict.PASS else
            ("no --udp-target" if verdict is Verdict.SKIP else f"behaviour {i}: answered 0002 to CycleOff without CycleOn"),
            expected="an answer 0000 within time_out", observed="answered 0000 after 0.4 ms",
            sent_hex=POSE, received_hex=ANSWER, pcap=f"pcaps/case-{i}.pcapng", wire=_wire(wire_n, i),
            latencies_ms=[0.4 + (k % 11) * 0.05 for k in range(500)] if i % 3 == 0 else [],
        ))
    return cases


def systematic_defect(cases: list[CaseResult], fails: int = 150, non_strict: int = 60,
                      inconclusive: int = 10) -> tuple[list[CaseResult], list[RootCause]]:
    """``cases`` as a box with one systematic defect (every answer's version byte-swapped)
    would leave them: the first ``fails`` PASS cases FAIL, the next ``non_strict`` are
    NON-STRICT, then ``inconclusive`` INCONCLUSIVE; all explained by one root cause RC1."""
    out, explained = [], []
    budget = {Verdict.FAIL: fails, Verdict.NON_STRICT: non_strict, Verdict.INCONCLUSIVE: inconclusive}
    order = [Verdict.FAIL, Verdict.NON_STRICT, Verdict.INCONCLUSIVE]
    bad_answer = "fefe010010230000000000000000"
    for case in cases:
        verdict = next((v for v in order if budget[v] > 0), None)
        if case.verdict is not Verdict.PASS or verdict is None:
            out.append(case)
            continue
        budget[verdict] -= 1
        first = case.clauses[0] if case.clauses else "A2"
        n = len(explained)
        requirement = f"{first}: " + WORDINGS[n % len(WORDINGS)].format(k=KINDS[(n // len(WORDINGS)) % len(KINDS)])
        out.append(dataclasses.replace(
            case, verdict=verdict, level=Level.SHOULD if verdict is Verdict.NON_STRICT else Level.MUST,
            message=f"{requirement}: expected answered POSE with error 0x0000 (OK); the box sent a malformed "
                    f"answer: [F2] version 0x0100, expected 0x0001 ({len(out)} bytes into the connection)",
            requirement=requirement,
            expected="answered POSE with error 0x0000 (OK) within time_out (5000 ms), or a close",
            observed="sent a malformed answer: [F2] version 0x0100, expected 0x0001; then nothing within 5000 ms; "
                     "the connection stayed open " * 3,
            sent_hex=POSE * 3, received_hex=bad_answer * 4, root_cause="RC1",
            wire=_wire(700 if len(explained) % 40 == 5 else 4 + len(explained) % 30, len(out)),
        ))
        explained.append(case.id)
    rc = RootCause("RC1", ("F2", "A2"), "every answer carries version 01 00 instead of 00 01", bad_answer,
                   explained, Level.MUST, "malformed-answers")
    return out, [rc]


def without_root_causes(cases: list[CaseResult]) -> list[CaseResult]:
    """The same run as a suite without root-cause analysis reports it: no case names one."""
    return [dataclasses.replace(c, root_cause=None) for c in cases]
