"""A run cut short (conformance/engine/signals.py): SIGTERM, SIGHUP and Ctrl-C still write the reports,
which say INCOMPLETE and list the cases not run; the exit status is 3."""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conformance.engine import signals


def test_deferred_holds_a_signal_until_the_evidence_is_written() -> None:
    signals.install()
    try:
        with pytest.raises(signals.Interrupted, match="SIGTERM"), signals.deferred():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)  # the handler runs here, and only remembers the signal
            written = True  # reached: the signal did not cut this block short
        assert written
    finally:
        signals.restore()


def test_install_makes_sigterm_a_keyboard_interrupt() -> None:
    signals.install()
    try:
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1.0)
    finally:
        signals.restore()
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


#: packets in T2-01's pcap once its stream is under way (each pose: request, answer and their ACKs)
STREAMING = 20


def _packets(pcap: Path) -> int:
    """Enhanced packet blocks in a pcapng file the run is still writing (a block cut short is not counted)."""
    try:
        data = pcap.read_bytes()
    except FileNotFoundError:
        return 0
    count, at = 0, 0
    while at + 12 <= len(data):
        kind, length = struct.unpack_from("<II", data, at)
        if length < 12 or at + length > len(data):
            break
        count += kind == 6
        at += length
    return count


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT], ids=["term", "hup", "int"])
def test_a_run_cut_short_writes_reports_that_say_incomplete(tmp_path: Path, sig: signal.Signals) -> None:
    reports, pcaps = tmp_path / "r", tmp_path / "p"
    cmd = [sys.executable, "-m", "conformance", "run", "--quiet", "--report-dir", str(reports),
           "--pcap-dir", str(pcaps), "--stream-seconds", "20", "--cases", "A4-*", "--cases", "T2-01", "--cases", "R1-1*"]
    # SIGINT as a terminal delivers it: with its default action in the child, whatever this worker inherited
    # (a process started with SIGINT ignored, as a background job of a shell is, passes that on to its children)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                            preexec_fn=_default_sigint)
    try:
        # Not just "T2-01 has begun" (its pcap exists): under load a run can still leave that state before the
        # signal lands. Once the stream's poses are in the pcap, T2-01 streams for its 20 s whatever the load.
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and _packets(pcaps / "T2-01.pcapng") < STREAMING:
            if proc.poll() is not None:
                pytest.fail(f"the run ended before it was interrupted: {proc.communicate()}")
            time.sleep(0.1)
        assert _packets(pcaps / "T2-01.pcapng") >= STREAMING, "the run never reached T2-01's stream"
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 3, (out, err)
    assert "INCOMPLETE" in out and "interrupted" in err
    doc = json.loads((reports / "summary.json").read_text())
    assert doc["suite"]["complete"] is False
    ran = {c["id"] for c in doc["cases"]}
    assert "A4-01" in ran  # before T2-01; the case in progress and the vector replays after it did not run
    assert "T2-01" in doc["suite"]["not_run"] and any(c.startswith("R1-1") for c in doc["suite"]["not_run"])
    assert set(doc["suite"]["not_run"]).isdisjoint(ran)
    assert doc["suite"]["cases_total"] == len(ran) + len(doc["suite"]["not_run"])
    html = (reports / "report.html").read_text()
    assert f"INCOMPLETE ({len(ran)} of {doc['suite']['cases_total']} cases run)" in html
    assert "CONFORMS" not in html.split("INCOMPLETE", 1)[0]
    assert (reports / "junit.xml").is_file()
    assert (pcaps / "T2-01.pcapng").stat().st_size > 0  # the evidence of the case in progress is kept
