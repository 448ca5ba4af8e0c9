"""The independent Node.js boxes of tests/impls/node (written from docs/PROTOCOL.md alone): a legal one is clean.

The whole held-out benchmark (every legal and defect box, full runs) is ``benchmarks/bench_heldout.py``;
here, the cases a legal box once broke, so a regression shows in CI."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BOX = ROOT / "tests" / "impls" / "node" / "box.js"

pytestmark = [pytest.mark.e2e, pytest.mark.impls,
              pytest.mark.skipif(shutil.which("node") is None or not BOX.exists(), reason="needs node and tests/impls/node")]


def _serve(name: str) -> tuple[subprocess.Popen[str], list[str]]:
    box = subprocess.Popen(["node", str(BOX), name, "--port", "0"], stdout=subprocess.PIPE, text=True)
    assert box.stdout is not None
    words = box.stdout.readline().split()
    args = ["--target", words[words.index("tcp") + 1]]
    if "args" in words:
        args += words[words.index("args") + 1:]
    return box, args


@pytest.mark.parametrize(("name", "cases"), [
    # resumes 12 bytes after a rejected header (R6 (b)) and refuses each with 00 FFFF: 64 KiB of FE swallow the
    # probe behind them, which is legal (it was FAILed A1 "no 0000 followed", with no root cause)
    ("legal-c", "R2-01*"),
])
def test_a_legal_node_box_is_clean(tmp_path: Path, name: str, cases: str) -> None:
    box, args = _serve(name)
    try:
        run = subprocess.run([sys.executable, "-m", "conformance", "run", *args, "--cases", cases, "--quiet",
                              "--report-dir", str(tmp_path), "--pcap-dir", str(tmp_path / "pcaps")],
                             capture_output=True, text=True, timeout=240, cwd=ROOT)
    finally:
        box.terminate()
        box.wait(10)
    summary = json.loads((tmp_path / "summary.json").read_text())
    bad = [(c["id"], c["verdict"], c.get("message", "")) for c in summary["cases"]
           if c["verdict"] in ("FAIL", "NON-STRICT", "ERROR")]
    assert run.returncode == 0 and not bad, (run.stdout[-2000:], bad)
    assert summary["totals"]["PASS"] >= 2
