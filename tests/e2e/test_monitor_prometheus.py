"""A real Prometheus scrapes ``monitor --metrics`` while a robot ↔ box session runs through it (issue 26).

Prometheus (the Debian package's /usr/bin/prometheus) runs on loopback with a temporary
configuration and storage directory, scraping every second, and loads the shipped alert
rules (docs/monitor/isight.rules.yml); the test asserts on the series through its HTTP
query API. ``promtool check rules`` validates the rules file. Every wait is bounded.
"""

from __future__ import annotations

import asyncio
import json
import shutil
import socket
import subprocess
import time
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from tests.impls.box import start_box
from tests.impls.robot import run_robot
from tests.monitor_util import monitored

ROOT = Path(__file__).resolve().parents[2]
RULES = ROOT / "docs" / "monitor" / "isight.rules.yml"
PROMETHEUS = shutil.which("prometheus") or "/usr/bin/prometheus"
PROMTOOL = shutil.which("promtool") or "/usr/bin/promtool"
needs_prometheus = pytest.mark.skipif(not Path(PROMETHEUS).exists(), reason="prometheus is not installed "
                                      "(Debian package prometheus; .ci/run installs it)")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=5) as r:
        return json.loads(r.read())


def _query(base: str, expr: str) -> list[dict[str, Any]]:
    doc = _get(f"{base}/api/v1/query?" + urllib.parse.urlencode({"query": expr}))
    assert doc["status"] == "success", doc
    return doc["data"]["result"]


def _value(base: str, expr: str, want: Any, bound: float = 40.0) -> float:
    """Poll ``expr`` until its first sample satisfies ``want`` (bounded); its value."""
    deadline = time.monotonic() + bound
    last: Any = None
    while time.monotonic() < deadline:
        try:
            result = _query(base, expr)
        except OSError:
            result = []
        if result:
            last = float(result[0]["value"][1])
            if want(last):
                return last
        time.sleep(0.5)
    raise AssertionError(f"{expr}: last value {last!r} within {bound:.0f} s")


@pytest.mark.skipif(not Path(PROMTOOL).exists(), reason="promtool is not installed (Debian package prometheus)")
def test_promtool_accepts_the_rules_file() -> None:
    out = subprocess.run([PROMTOOL, "check", "rules", str(RULES)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "SUCCESS" in out.stdout and "rules found" in out.stdout


@needs_prometheus
@pytest.mark.impls(seconds=20)
def test_prometheus_scrapes_a_live_session_through_the_monitor(tmp_path: Path) -> None:
    with start_box("resync-fine") as box:
        async def main() -> dict[str, float]:
            async with monitored(box.port, tmp_path, metrics=("127.0.0.1", 0)) as m:
                assert m.settings.metrics is not None
                metrics_port = m.settings.metrics[1]
                prom_port = _free_port()
                config = tmp_path / "prometheus.yml"
                config.write_text(
                    "global:\n  scrape_interval: 1s\n  evaluation_interval: 1s\n"
                    f"rule_files:\n  - {RULES}\n"
                    "scrape_configs:\n  - job_name: isight-monitor\n    static_configs:\n"
                    f"      - targets: ['127.0.0.1:{metrics_port}']\n")
                log = (tmp_path / "prometheus.log").open("wb")
                prom = subprocess.Popen([PROMETHEUS, f"--config.file={config}",
                                         f"--storage.tsdb.path={tmp_path / 'tsdb'}",
                                         f"--web.listen-address=127.0.0.1:{prom_port}"],
                                        stdout=log, stderr=subprocess.STDOUT, cwd=tmp_path)
                try:
                    return await asyncio.to_thread(_session_and_queries, m, f"http://127.0.0.1:{prom_port}")
                finally:
                    prom.terminate()
                    try:
                        prom.wait(20)
                    except subprocess.TimeoutExpired:
                        prom.kill()
                        prom.wait(10)
                    log.close()

        got = asyncio.run(main())
    assert got["up"] == 1
    assert got["poses_sent"] >= 20 and got["poses_answered"] >= 20
    assert got["commands"] >= 2  # CycleOn and CycleOff
    assert got["answers_0000"] >= got["poses_answered"]
    assert 0 < got["stream_p50_s"] < 5.0  # the box answers well within time_out on loopback
    assert got["connections_total"] == 2 and got["sessions"] == 1
    assert got["ring_bytes"] > 0
    assert got["rules_ok"] == 1


def _session_and_queries(m: Any, base: str) -> dict[str, float]:
    deadline = time.monotonic() + 60
    while True:  # Prometheus is ready
        try:
            with urllib.request.urlopen(f"{base}/-/ready", timeout=2) as r:
                if r.status == 200:
                    break
        except OSError:
            pass
        if time.monotonic() > deadline:
            raise AssertionError("prometheus did not become ready within 60 s")
        time.sleep(0.3)
    got: dict[str, float] = {"up": _value(base, 'up{job="isight-monitor"}', lambda v: v == 1)}
    outcome = run_robot("canonical", m.target, duration=3.0)  # scraped while it runs
    assert outcome.exit_code == 0, outcome
    got["poses_sent"] = _value(base, 'isight_frames_total{direction="robot_to_box",action="POSE"}',
                               lambda v: v >= outcome.poses_sent)
    got["poses_answered"] = _value(base, 'isight_frames_total{direction="box_to_robot",action="POSE"}',
                                   lambda v: v >= outcome.poses_answered)
    got["commands"] = _value(base, 'sum(isight_frames_total{direction="robot_to_box",action=~"CYCLE_O.*"})',
                             lambda v: v >= 2)
    got["answers_0000"] = _value(base, 'isight_answers_total{error_code="0x0000"}', lambda v: v >= 2)
    got["stream_p50_s"] = _value(base, 'histogram_quantile(0.5, sum by (le) '
                                 '(isight_answer_latency_seconds_bucket{kind="stream"}))', lambda v: v == v)
    got["connections_total"] = _value(base, "isight_connections_total", lambda v: v >= 2)
    got["sessions"] = _value(base, "isight_sessions_total", lambda v: v >= 1)
    got["ring_bytes"] = _value(base, "isight_ring_bytes", lambda v: v > 0)
    rules = _get(f"{base}/api/v1/rules")["data"]["groups"]
    got["rules_ok"] = float(bool(rules) and all(r.get("health") in ("ok", "unknown") for g in rules
                                                for r in g["rules"]) and rules[0]["name"] == "isight-monitor")
    return got
