"""How many A4 pages report.html prints to, for a conforming box and for a box with one
systematic defect (issue 13: at most 15 and 40).

Steps (all on loopback; each bounded in time):

1. ``isight-conformance run`` against the bundled reference box in a child process
   (about 25 s), or ``--summary DIR`` to use the reports of an earlier run instead;
2. its report.html printed with headless Chromium (``--print-to-pdf``): the conforming box;
3. its summary.json loaded back and perturbed as a box whose every answer is malformed
   leaves a run: ~150 FAIL under one root cause, 60 NON-STRICT, 10 INCONCLUSIVE, each with
   hex, expected/observed text and a wire log (``tests/reportruns.py``); printed with its
   root cause, and again without (a suite that reports no root cause);
4. the synthetic runs of the print test (tests/e2e/test_report_print.py), for comparison.

    python benchmarks/bench_report_print.py
    python benchmarks/bench_report_print.py --summary reports/20260509-073525
    python benchmarks/bench_report_print.py --lang zh-CN     # the Chinese report (needs a CJK font)

Prints one line per document: pages, PDF size, HTML size, seconds to print.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from conformance import i18n  # noqa: E402
from conformance.model.verdicts import CaseResult, RootCause, SuiteInfo  # noqa: E402
from conformance.report.html import write_html  # noqa: E402
from conformance.report.load import cases_of, load_summary, root_causes_of, suite_of  # noqa: E402
from tests.reportruns import (  # noqa: E402
    chromium,
    conforming_run,
    print_to_pdf,
    systematic_defect,
    without_root_causes,
)

LIMITS = {"conforming": 15, "broken": 40}


def real_run(workdir: Path, lang: str) -> Path:
    """Reports of ``isight-conformance run`` against the bundled reference box."""
    report_dir = workdir / "reports"
    cmd = [sys.executable, "-m", "conformance", "run", "--quiet", "--report-dir", str(report_dir),
           "--pcap-dir", str(workdir / "pcaps"), "--lang", lang]
    start = time.monotonic()
    done = subprocess.run(cmd, cwd=workdir, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=900)
    if done.returncode not in (0, 1) or not (report_dir / "summary.json").is_file():
        raise SystemExit(f"isight-conformance run failed (exit {done.returncode}): {done.stderr[-500:]}")
    print(f"isight-conformance run: {time.monotonic() - start:.0f} s, exit {done.returncode}")
    return report_dir


def measure(label: str, html: Path, limit: int | None) -> int:
    pdf = html.with_suffix(".pdf")
    start = time.monotonic()
    pages = print_to_pdf(html, pdf)
    took = time.monotonic() - start
    verdict = "" if limit is None else f" (limit {limit}: {'ok' if pages <= limit else 'OVER'})"
    print(f"{label:<58} {pages:>4} pages{verdict}  PDF {pdf.stat().st_size / 1e6:5.2f} MB  "
          f"HTML {html.stat().st_size / 1e6:5.2f} MB  {took:4.1f} s")
    return pages


def render(path: Path, suite: SuiteInfo, cases: list[CaseResult], root_causes: list[RootCause]) -> Path:
    write_html(path, suite, cases, root_causes=root_causes)
    return path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--summary", metavar="DIR", help="an earlier run's report directory (skip the run)")
    parser.add_argument("--fails", type=int, default=150, help="FAIL cases of the systematic defect (default 150)")
    parser.add_argument("--lang", choices=i18n.LANGS, default="en", help="the report's language (default en)")
    args = parser.parse_args()
    with i18n.language(args.lang):
        return measure_all(args)


def measure_all(args: argparse.Namespace) -> int:
    if chromium() is None:
        print("no chromium binary: nothing to measure", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="bench-report-print-") as tmp:
        work = Path(tmp)
        report_dir = Path(args.summary) if args.summary else real_run(work, args.lang)
        doc = load_summary(report_dir)
        suite, cases = suite_of(doc), cases_of(doc)
        over = 0
        if (report_dir / "report.html").is_file():
            name = "report.html as the run wrote it" + ("" if args.summary else " (reference box)")
            over += measure(name, report_dir / "report.html", None if args.summary else LIMITS["conforming"]) > \
                LIMITS["conforming"] and not args.summary
        broken, rcs = systematic_defect(cases, fails=args.fails)
        counts = {v: sum(1 for c in broken if c.verdict.value == v) for v in ("FAIL", "NON-STRICT", "INCONCLUSIVE")}
        print(f"systematic defect: {counts['FAIL']} FAIL, {counts['NON-STRICT']} NON-STRICT, "
              f"{counts['INCONCLUSIVE']} INCONCLUSIVE; root cause RC1 explains {len(rcs[0].cases)}")
        runs = [
            ("run perturbed: systematic defect, one root cause", broken, rcs, "broken"),
            ("run perturbed: systematic defect, no root cause reported", without_root_causes(broken), [], "broken"),
            ("synthetic conforming run (the print test's)", conforming_run(), [], "conforming"),
        ]
        synthetic, synthetic_rcs = systematic_defect(conforming_run(), fails=args.fails)
        runs.append(("synthetic systematic defect (the print test's)", synthetic, synthetic_rcs, "broken"))
        for i, (label, run_cases, run_rcs, kind) in enumerate(runs):
            html = render(work / f"doc-{i}.html", suite, run_cases, run_rcs)
            over += measure(label, html, LIMITS[kind]) > LIMITS[kind]
        existing = ", ".join(rc.id for rc in root_causes_of(doc))
        if existing:
            print(f"(the run itself reported root causes {existing})")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
