"""The suite against tests/impls/selectbox, end to end: a box written from PROTOCOL.md alone.

selectbox answers from one thread with a random latency per request, in two or three pieces,
refuses non-requests under action 00 or by closing, and keeps the cycle per connection. Each
configuration is conforming, so the whole catalogue (fuzz cases included) must come out clean:
exit 0 and no FAIL, ERROR or NON-STRICT. Two configurations, about 2.5 minutes each on a
loaded 2-core machine; the box and the suite each have a hard wall-clock bound.
"""

from __future__ import annotations

import json
import os
import selectors
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.impls
ROOT = Path(__file__).resolve().parents[2]
LIMIT_S = 420  # the suite's wall-clock bound

#: configuration -> the profile flags its readings need (PROFILE-01 prints them)
RUNS = {
    "a5err": (),  # first index 0, no extension, refusals under action 00, resynchronises after garbage
    "ext1-close": ("--first-index", "1", "--checking", "lenient"),  # extension E, closes on garbage, any float
}


def first_line(proc: subprocess.Popen[str], wait_s: float = 20) -> str:
    assert proc.stdout is not None
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        if not sel.select(wait_s):
            return ""
    return proc.stdout.readline().strip()


@pytest.mark.parametrize("config", [pytest.param(c, marks=pytest.mark.impls(seconds=150)) for c in RUNS])
def test_selectbox_comes_out_clean(config: str, tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    box = subprocess.Popen([sys.executable, "-m", "tests.impls.selectbox", "--config", config, "--port", "0",
                            "--seed", "1"], cwd=ROOT, env=env, stdout=subprocess.PIPE, text=True)
    try:
        line = first_line(box)
        assert line.startswith("listening tcp 127.0.0.1:"), line
        report = tmp_path / "report"
        suite = subprocess.run([sys.executable, "-m", "conformance", "run", "--target", line.split()[2], "--quiet",
                                "--capture", "off", "--report-dir", str(report), *RUNS[config]],
                               cwd=tmp_path, env=env, capture_output=True, text=True, timeout=LIMIT_S)
    finally:
        box.kill()
        box.wait(10)
    summary = json.loads((report / "summary.json").read_text())
    bad = {c["id"]: f"{c['verdict']}: {c.get('message', '')[:200]}" for c in summary["cases"]
           if c["verdict"] in ("FAIL", "ERROR", "NON-STRICT")}
    assert suite.returncode == 0 and not bad, (suite.returncode, bad, suite.stdout[-2000:], suite.stderr[-2000:])
    assert summary["totals"]["PASS"] > 150, summary["totals"]  # the catalogue ran, not a handful of cases
