"""Death first (processes): boxes that die on a state sequence, on one connection and across two, are reported
as R2 (with the trigger's clause) before anything else; with --restart-cmd the death is confirmed by replaying
the session after a restart, and the box's last words (a Python traceback) are attached."""

from __future__ import annotations

import json
import shlex
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from conformance.commands import main
from conformance.fuzz.campaign import Campaign, CampaignConfig
from conformance.fuzz.death import STOPPED
from conformance.harness.target import Target

pytestmark = pytest.mark.timeout(300)

BOX = Path(__file__).resolve().parents[1] / "impls" / "dying_box.py"
TRIGGER = {"same": "the same connection", "cross": "another connection"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.parametrize("death", ["same", "cross"])
def test_a_box_dying_on_a_state_sequence_is_r2_first_confirmed_with_its_last_words(
        death: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()
    cmd = f"{shlex.quote(sys.executable)} {shlex.quote(str(BOX))} --port {port} --death {death}"
    code = main(["fuzz", "--target", f"127.0.0.1:{port}", "--restart-cmd", cmd, "--stateful-share", "1",
                 "--duration", "120", "--until-first", "--extension", "off", "--database", "none", "--seed", "1",
                 "--report-dir", str(tmp_path / "r"), "--pcap-dir", str(tmp_path / "p"), "--quiet"])
    out = capsys.readouterr().out
    assert code == 1, out
    first = next(line for line in out.splitlines() if line.startswith("  FAIL"))
    assert first.startswith("  FAIL 1 [R2, A1] R2: the box stays alive"), first
    assert "confirmed: after a restart" in first and "not confirmed" not in first
    summary = json.loads((tmp_path / "r" / "fuzz-summary.json").read_text())
    assert summary["stopped"] == "the first confirmed finding (--until-first)"
    failure = summary["failures"][0]
    assert failure["clauses"][:2] == ["R2", "A1"] and failure["confirmed"] is True
    assert failure["keys"][0].startswith("R2/death/session/")
    words = failure["last_words"]
    assert words["kind"] == "traceback" and words["exit_status"] == 70 and words["incarnation"] == 1
    assert words["headline"].startswith("Python traceback: PlantedDeath") and TRIGGER[death] in words["headline"]
    assert f"box: the box (incarnation 1, pid {words['pid']}) exit status 70: Python traceback" in out
    notes = json.loads(Path(failure["vector"]).read_text())["notes"]
    assert "PlantedDeath" in notes["BoxLastWords"]
    assert Path(failure["sequence"]).is_file()


def test_without_a_restart_the_death_is_still_r2_and_first(tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, str(BOX), "--port", "0", "--death", "cross"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        port = int(proc.stdout.readline().split()[1])
        config = CampaignConfig(target=Target("127.0.0.1", port), seed=2, max_examples=400, stateful_share=1.0,
                                extension=False, recover_s=1.0, report_dir=tmp_path / "r", pcap_dir=tmp_path / "p",
                                log=lambda _: None)
        result = Campaign(config).run()
        assert proc.wait(30) == 70  # it died
    finally:
        proc.kill()
        proc.wait(10)
    assert result.failures, result
    first = result.failures[0]
    assert first.clauses[:2] == ["R2", "A1"] and first.keys[0].startswith("R2/death/session/")
    assert not first.confirmed and "the box did not come back" in first.message
    assert first.last_words is None  # the test started the box, not the campaign: nothing of it was kept
    assert result.stopped == STOPPED
