"""``isight-conformance soak`` end to end (issue 38): compressed soaks (tens of seconds, windows of
2 s, cycles and events sped up) of legal boxes, which pass clean, and of boxes that fail only over
time, each caught with its slope or its N; and SIGINT, which ends a soak with its evidence kept.

The Node.js boxes (``tests/impls/node/box.js``, ``soak-a`` … ``soak-d``; their catalogue
``tests/impls/node/soak/CATALOGUE.json``) were written by someone else from PROTOCOL.md: the soak
meets them as a new user would.
"""

from __future__ import annotations

import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
NODE_BOX = ROOT / "tests" / "impls" / "node" / "box.js"
NODE = shutil.which("node")
#: a compressed soak: windows of 2 s, half-second cycles, two robots, every kind of event
COMPRESSED = {"window": "2s", "cycle-s": "0.5", "robots": "2", "events": "0.15", "stall-s": "0.5", "ghost-hold": "60s"}


def compressed(**changes: str) -> list[str]:
    """The compressed soak's options, with ``changes`` (``event_kinds="vanish"``)."""
    options = {**COMPRESSED, **{k.replace("_", "-"): v for k, v in changes.items()}}
    return [word for key, value in options.items() for word in (f"--{key}", value)] + ["--quiet"]


def soak(report: Path, *args: str, timeout: float = 180) -> tuple[int, dict[str, Any], str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "conformance", "soak", "--report-dir", str(report), *args],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout)
    doc = json.loads((report / "soak.json").read_text()) if (report / "soak.json").exists() else {}
    return proc.returncode, doc, proc.stdout + proc.stderr


def python_box(name: str) -> str:
    return f"{shlex.quote(sys.executable)} -m tests.impls.soak_box {name} --port 0"


def verdicts(doc: dict[str, Any]) -> dict[str, str]:
    return {v["clause"]: v["verdict"] for v in doc["verdicts"]}


def trend(doc: dict[str, Any], key: str, series: str) -> dict[str, Any]:
    return next(t for t in doc[key] if t["series"] == series)


def assert_clean(code: int, doc: dict[str, Any], out: str) -> None:
    assert code == 0, out
    assert doc["complete"] and doc["overall"] == "PASS", out
    assert not doc["findings"], doc["findings"]
    assert set(verdicts(doc).values()) == {"PASS"}, out
    assert doc["totals"]["sessions"] >= 20 and doc["totals"]["failed"] == 0
    t2 = next(v for v in doc["verdicts"] if v["clause"] == "T2")
    assert "flat over" in t2["message"] and "sessions" in t2["message"]  # how long and how many it covers


@pytest.mark.impls(seconds=30)
def test_the_bundled_box_passes_a_compressed_soak_clean_with_every_event(tmp_path):
    code, doc, out = soak(tmp_path, "--duration", "24s", *compressed(events="0.3"))
    assert_clean(code, doc, out)
    assert set(doc["totals"]["events"]) == {"vanish", "reset", "stall", "burst"}
    assert doc["half_open"]["abandoned"] >= 2  # a vanished robot's two connections
    assert doc["box"]["pid"] > 0 and doc["windows"][-1]["resources"]["rss_mb"] > 0  # watched as a child
    for name in ("summary.json", "junit.xml", "report.html"):
        assert (tmp_path / name).stat().st_size > 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert {c["id"] for c in summary["cases"]} == {"SOAK-S1", "SOAK-S4", "SOAK-S5", "SOAK-R5", "SOAK-T1", "SOAK-T2"}
    page = (tmp_path / "report.html").read_text()
    assert page.count("<svg") >= 3 and "http" not in page.split("<body>")[0]  # plots inline, no CDN


@pytest.mark.impls(seconds=30)
@pytest.mark.parametrize("name", ["slow", "stalling"])
def test_legal_slow_and_stalling_boxes_pass_clean(tmp_path, name):
    assert_clean(*soak(tmp_path, "--restart-cmd", python_box(name), "--duration", "24s", *compressed()))


@pytest.mark.impls(seconds=30)
def test_a_box_with_one_cycle_for_all_robots_passes_clean_when_robots_vanish_mid_cycle(tmp_path):
    # two robots share the box's one cycle (S3: CycleOn while it runs 0001, CycleOff idle 0002, both legal),
    # and a robot that vanishes mid-cycle leaves it running: the rebooted robot ends it first (a CycleOff)
    code, doc, out = soak(tmp_path, "--restart-cmd", python_box("one-cycle"), "--duration", "24s",
                          *compressed(events="0.25", event_kinds="vanish,reset"))
    assert_clean(code, doc, out)
    not_ready = sum(r["sessions_not_ready"] for r in doc["windows"])
    assert doc["totals"]["served"] > not_ready, (doc["totals"], not_ready)  # the soak kept playing


@pytest.mark.impls(seconds=30)
def test_a_box_leaking_memory_per_connection_is_a_finding_with_its_slope(tmp_path):
    # 256 KiB kept per connection, two per session (no bursts here): 0.5 MiB per session = 524 MB per 1,000
    code, doc, out = soak(tmp_path, "--restart-cmd", python_box("leak-rss"), "--duration", "24s", *compressed(event_kinds="vanish,reset,stall"))
    assert code == 0 and doc["overall"] == "PASS with findings", out
    rss = trend(doc, "resource_trends", "rss_mb")
    assert rss["grows"] and 350 <= rss["per_1000_sessions"]["slope"] <= 700, rss
    assert any(f.startswith("RSS +") and "per 1,000 sessions (95 % CI" in f for f in doc["findings"])
    assert verdicts(doc)["R5"] == "INFORMATIONAL"


@pytest.mark.impls(seconds=30)
def test_a_box_whose_latency_creeps_up_fails_t2_with_its_slope(tmp_path):
    # 0.5 ms more per session the box served: 500 ms per 1,000 sessions
    code, doc, out = soak(tmp_path, "--restart-cmd", python_box("latency-creep"), "--duration", "24s", *compressed())
    assert code == 1 and verdicts(doc)["T2"] == "FAIL", out
    p50 = trend(doc, "latency_trends", "latency p50")
    assert 300 <= p50["per_1000_sessions"]["slope"] <= 800, p50
    t2 = next(v for v in doc["verdicts"] if v["clause"] == "T2")
    assert t2["windows"] and "per 1,000 sessions" in t2["message"]


@pytest.mark.impls(seconds=30)
def test_a_box_that_never_closes_closed_connections_grows_descriptors(tmp_path):
    code, doc, out = soak(tmp_path, "--restart-cmd", python_box("fd-leak"), "--duration", "24s", *compressed(event_kinds="vanish,reset,stall"))
    assert code == 0 and doc["findings"], out
    fds = trend(doc, "resource_trends", "fds")
    assert fds["grows"] and 1500 <= fds["per_1000_sessions"]["slope"] <= 2600, fds  # two per session
    assert doc["windows"][-1]["resources"]["close_wait"] > 10


@pytest.mark.impls(seconds=20)
def test_a_box_that_stops_after_n_sessions_fails_s5_with_n(tmp_path):
    code, doc, out = soak(tmp_path, "--restart-cmd", python_box("stop-after"), "--duration", "40s", *compressed(time_out="2000"))
    assert code == 1 and verdicts(doc)["S5"] == "FAIL", out
    assert doc["ended_by"] == "stopped serving" and doc["elapsed_s"] < 35  # it did not soak a dead box
    assert 6 <= doc["stopped"]["after_sessions"] <= 12  # the box counts a burst's and the probe's connections too
    s5 = next(v for v in doc["verdicts"] if v["clause"] == "S5")
    assert f"after {doc['stopped']['after_sessions']} sessions" in s5["message"]


@pytest.mark.impls(seconds=40)
def test_a_box_that_never_frees_abandoned_connections_fails_r5_with_n(tmp_path):
    code, doc, out = soak(tmp_path, "--restart-cmd", python_box("half-open-cap"), "--duration", "40s",
                          *compressed(events="0.5", event_kinds="vanish", ghost_hold="300s", time_out="2000"))
    assert code == 1 and verdicts(doc)["R5"] == "FAIL", out
    r5 = next(v for v in doc["verdicts"] if v["clause"] == "R5")
    # the soak reset the abandoned connections of the stopped box, and it served again: they held it
    assert "served again once the soak reset them" in r5["message"], r5
    assert r5["details"]["held"][0]["half_open"] >= 2 and any("held it (R5)" in n for n in doc["notes"])


@pytest.mark.impls(seconds=15)
def test_a_box_whose_process_dies_fails_s5_with_n_and_its_last_words(tmp_path):
    code, doc, out = soak(tmp_path, "--restart-cmd", python_box("dies-after"), "--duration", "40s", *compressed())
    assert code == 1 and doc["ended_by"] == "box died" and doc["stopped"]["kind"] == "died", out
    assert "fatal: session table full" in doc["stopped"]["reason"]
    assert "exit status 70" in doc["box_last_words"]["summary"]
    assert verdicts(doc)["S5"] == "FAIL" and 4 <= doc["stopped"]["after_sessions"] <= 10


def test_sigint_ends_the_soak_and_keeps_its_evidence(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "conformance", "soak", "--duration", "2h", "--window", "1s",
                             "--cycle-s", "0.3", "--report-dir", str(tmp_path), "--quiet"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            path = tmp_path / "soak.json"
            if path.exists() and len(json.loads(path.read_text())["windows"]) >= 3:
                break
            time.sleep(0.2)
        else:
            pytest.fail("no checkpoint with three windows within 60 s")
        checkpoint = json.loads((tmp_path / "soak.json").read_text())
        assert not checkpoint["final"] and checkpoint["ended_by"] == "running"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 3, err
    assert "Traceback" not in err
    doc = json.loads((tmp_path / "soak.json").read_text())
    assert doc["final"] and not doc["complete"] and doc["ended_by"] == "signal"
    assert len(doc["windows"]) >= len(checkpoint["windows"])  # nothing measured was lost
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["suite"]["complete"] is False and summary["cases"]


# -- the Node.js boxes nobody on this project wrote ------------------------------------------------------------
def node_catalogue() -> dict[str, dict[str, Any]]:
    path = NODE_BOX.parent / "soak" / "CATALOGUE.json"
    return {e["name"]: e for e in json.loads(path.read_text())} if path.exists() else {}


needs_node = pytest.mark.skipif(NODE is None or not NODE_BOX.exists(),
                                reason="node or tests/impls/node/box.js is missing")


def node_box(name: str) -> str:
    if name not in node_catalogue():
        pytest.skip(f"{name} is not in tests/impls/node/soak/CATALOGUE.json")
    return f"{NODE} {shlex.quote(str(NODE_BOX))} {name} --port 0"


@needs_node
@pytest.mark.impls(seconds=35)
def test_node_soak_a_memory_per_closed_connection_is_found(tmp_path):
    code, doc, out = soak(tmp_path, "--restart-cmd", node_box("soak-a"), "--duration", "30s", *compressed())
    rss = trend(doc, "resource_trends", "rss_mb")
    assert rss["grows"], out
    # 100 KiB per closed connection: two per session, ten per burst
    assert 150 <= rss["per_1000_sessions"]["slope"] <= 450 and rss["per_1000_sessions"]["low"] > 0, rss


@needs_node
@pytest.mark.impls(seconds=35)
def test_node_soak_b_growing_latency_fails_t2(tmp_path):
    code, doc, out = soak(tmp_path, "--restart-cmd", node_box("soak-b"), "--duration", "30s", *compressed())
    assert code == 1 and verdicts(doc)["T2"] == "FAIL", out
    p50 = trend(doc, "latency_trends", "latency p50")
    assert p50["per_hour"]["low"] > 0


@needs_node
@pytest.mark.impls(seconds=45)
def test_node_soak_c_abandoned_connections_never_freed_fails_r5(tmp_path):
    code, doc, out = soak(tmp_path, "--restart-cmd", node_box("soak-c"), "--duration", "60s", "--window", "2s",
                          "--cycle-s", "0.5", "--robots", "4", "--events", "0.5", "--event-kinds", "vanish",
                          "--ghost-hold", "300s", "--time-out", "2000", "--quiet")
    assert code == 1 and verdicts(doc)["R5"] == "FAIL", out
    r5 = next(v for v in doc["verdicts"] if v["clause"] == "R5")
    assert "served again once the soak reset them" in r5["message"], r5
    assert r5["details"]["held"][0]["half_open"] >= 64  # the box's limit: 64 abandoned connections


@needs_node
@pytest.mark.impls(seconds=45)
def test_node_soak_d_stops_after_n_sessions_fails_s5_with_n(tmp_path):
    code, doc, out = soak(tmp_path, "--restart-cmd", node_box("soak-d"), "--duration", "60s", "--window", "2s",
                          "--cycle-s", "0.3", "--robots", "4", "--time-out", "2000", "--quiet")
    assert code == 1 and verdicts(doc)["S5"] == "FAIL", out
    # the box counts connections (300); a soak session is two of them, plus the extension probe's
    assert 120 <= doc["stopped"]["after_sessions"] <= 160, doc["stopped"]
