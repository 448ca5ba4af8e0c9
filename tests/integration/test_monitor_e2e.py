"""The monitor with real parts: the robot simulator ↔ monitor ↔ the reference box or a box from tests/impls.

Each test runs one short robot session (about 1-3 s) through the monitor in-process.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
from pathlib import Path

import pytest

from conformance.analyze import AnalyzeConfig, analyze, build_cases
from conformance.endpoints.bundled import start_bundled
from conformance.endpoints.robot import RobotSession
from conformance.protocol import DEFAULT_PROFILE
from tests.impls.box import start_box
from tests.impls.robot import run_robot as run_impl_robot
from tests.monitor_util import monitored


@pytest.fixture
def box():  # type: ignore[no-untyped-def]
    bundled = start_bundled(DEFAULT_PROFILE)
    yield bundled
    bundled.stop()


def _robot(target: tuple[str, int], **kw):  # type: ignore[no-untyped-def]
    return RobotSession(target, DEFAULT_PROFILE, duration=kw.pop("duration", 0.5), **kw)


def _verdicts(cases) -> dict[str, tuple[str, str]]:  # type: ignore[no-untyped-def]
    return {c.id: (c.verdict.value, c.message) for c in cases}


def test_clean_session_through_the_monitor_and_analyze_agrees(box, tmp_path: Path) -> None:
    async def main():  # type: ignore[no-untyped-def]
        async with monitored(box.target.port, tmp_path) as m:
            result = await _robot(m.target).run()
            extension = await _robot(m.target, extension=True, result_wait=0.1).run()
            await m.settled()  # the box's closes pass through before the monitor stops
        return m, result, extension

    m, result, extension = asyncio.run(main())
    assert result.ok and extension.ok, (result.reason, extension.reason)
    assert result.poses_answered == result.poses_sent > 10
    # the stream's send jitter (T2) depends on the machine's load, not on the monitor: not asserted
    assert {k: v for k, v in m.failing().items() if not k.startswith("OBS-T2-")} == {}
    doc = m.monitor_json()
    assert doc["connections"] == 4 and doc["sessions"] == 2
    assert [c for c in doc["root_causes"] if c["clause"] != "T2"] == []
    verdicts = m.verdicts()
    assert verdicts["OBS-S1-robot"] == "PASS" and verdicts["OBS-E4-robot"] == "PASS"
    assert verdicts["OBS-T1-box"] == "PASS" and verdicts["OBS-A1-box"] == "PASS"
    assert _analyze_agrees(m, tmp_path, box.target.port).ctx.stats.sessions == 2


def _analyze_agrees(m, tmp_path: Path, port: int, profile=DEFAULT_PROFILE):  # type: ignore[no-untyped-def]
    """analyze on the monitor's own capture finds exactly what the monitor found."""
    pcaps = sorted((tmp_path / "pcaps").glob("*.pcapng"))
    assert len(pcaps) == 1
    analysis = analyze(pcaps[0], AnalyzeConfig(profile=profile, ports=(port,), heuristic=False))
    monitor_cases = {k: v for k, v in _verdicts(m.outcome.cases).items() if k.startswith("OBS-")}
    assert _verdicts(build_cases(analysis)) == monitor_cases
    return analysis


def test_bytes_pass_unchanged_and_the_box_log_matches(box, tmp_path: Path) -> None:
    """What the robot simulator saw equals what went through: poses answered one for one, latency recorded."""
    async def main():  # type: ignore[no-untyped-def]
        async with monitored(box.target.port, tmp_path) as m:
            result = await _robot(m.target, ping=True).run()
        return m, result

    m, result = asyncio.run(main())
    assert result.ok
    doc = m.monitor_json()
    assert doc["bytes"]["robot"] == 14 * 3 + 39 * result.poses_sent  # NONE, CycleOn, CycleOff (14 bytes), poses (39)
    assert doc["latency_ms"]["n"] == 3  # NONE, CycleOn, CycleOff
    n = result.poses_sent + 3
    assert doc["frames"] == {"robot": n, "box": n, "poses": result.poses_sent}


@pytest.mark.parametrize(("variant", "clause"), [("swapped-version", "F2"), ("late-cycle-on", "T1")])
def test_a_broken_box_is_blamed_with_its_clause(tmp_path: Path, variant: str, clause: str) -> None:
    # late-cycle-on answers after 6 s; 2 s (not 1) so that a loaded runner still connects the robot within time_out
    profile = dataclasses.replace(DEFAULT_PROFILE, time_out_ms=2000)
    with start_box(variant) as impl:
        async def main():  # type: ignore[no-untyped-def]
            async with monitored(impl.port, tmp_path, profile=profile) as m:
                result = await RobotSession(m.target, profile, duration=0.3).run()
            return m, result

        m, result = asyncio.run(main())
    assert not result.ok
    failing = m.failing()
    assert failing.get(f"OBS-{clause}-box") == "FAIL", failing
    roots = m.summary()["root_causes"]
    assert roots[0]["title"].startswith("box:"), roots
    assert clause in {rc["clauses"][0] for rc in roots if rc["title"].startswith("box:")}
    _analyze_agrees(m, tmp_path, impl.port, profile)
    assert f"FAIL BOX {clause}" in m.view_out.getvalue()  # printed as it happened


@pytest.mark.parametrize(("variant", "clause"), [("transfer-10", "F3"), ("cycle-on-first", "S1")])
def test_a_broken_robot_is_blamed_with_its_clause(box, tmp_path: Path, variant: str, clause: str) -> None:
    profile = dataclasses.replace(DEFAULT_PROFILE, time_out_ms=1000)

    async def main():  # type: ignore[no-untyped-def]
        async with monitored(box.target.port, tmp_path, profile=profile) as m:
            await asyncio.to_thread(run_impl_robot, variant, m.target, duration=0.5, time_out=1.0)
        return m

    m = asyncio.run(main())
    failing = m.failing()
    assert failing.get(f"OBS-{clause}-robot") == "FAIL", failing
    assert not any(k.endswith("-box") for k in failing), failing
    roots = m.summary()["root_causes"]
    assert roots[0]["title"].startswith("robot:") and roots[0]["clauses"] == [clause], roots
    _analyze_agrees(m, tmp_path, box.target.port, profile)


def test_the_reports_are_whole_json_and_name_the_ring(box, tmp_path: Path) -> None:
    async def main():  # type: ignore[no-untyped-def]
        async with monitored(box.target.port, tmp_path) as m:
            await _robot(m.target).run()
        return m

    m = asyncio.run(main())
    for name in ("summary.json", "monitor.json"):
        json.loads((m.report_dir / name).read_text())
    assert (m.report_dir / "junit.xml").read_text().startswith("<?xml")
    assert "live line" in (m.report_dir / "report.html").read_text()
    assert m.monitor_json()["ring"][0] == {"file": "monitor_00001.pcapng", "first_frame": 1}


def test_the_live_panel_on_a_terminal(box, tmp_path: Path) -> None:
    async def main():  # type: ignore[no-untyped-def]
        async with monitored(box.target.port, tmp_path, tty=True) as m:
            await _robot(m.target).run()
            await asyncio.sleep(0.6)  # one refresh of the panel after the session
        return m

    m = asyncio.run(main())
    shown = m.view_out.getvalue()
    for row in ("connections", "sessions completed", "frames", "answer latency", "pose stream", "root causes"):
        assert row in shown
    assert "robot → box" in shown and "2 in all" in shown
