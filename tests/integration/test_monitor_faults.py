"""Every fault kind against the robot simulator, through the monitor, in front of the reference box.

time_out is 1000 ms here, so a session the fault ends takes about a second.
"""

from __future__ import annotations

import asyncio
import dataclasses
from pathlib import Path

import pytest

from conformance.endpoints.bundled import start_bundled
from conformance.endpoints.robot import RobotSession
from conformance.protocol import DEFAULT_PROFILE
from tests.monitor_util import monitored, pcapng_comments

PROFILE = dataclasses.replace(DEFAULT_PROFILE, time_out_ms=1000)


@pytest.fixture(scope="module")
def box():  # type: ignore[no-untyped-def]
    bundled = start_bundled(PROFILE)
    yield bundled
    bundled.stop()


def _through(box, tmp_path: Path, faults: list[str]):  # type: ignore[no-untyped-def]
    async def main():  # type: ignore[no-untyped-def]
        async with monitored(box.target.port, tmp_path, faults=faults, profile=PROFILE) as m:
            result = await RobotSession(m.target, PROFILE, duration=0.4).run()
            await asyncio.sleep(0.05)  # the robot's last close reaches the monitor
        return m, result

    return asyncio.run(main())


#: spec, the robot simulator's exit status (0 clean, 1 the box broke the protocol, 3 not ready,
#: 4 no answer within time_out, 5 connection closed), what the robot did next (a word of it)
CASES = [
    ("delay:CYCLE_ON:300", 0, "carried on"),
    ("delay:CYCLE_ON:1500", 4, "closed"),
    ("drop:CYCLE_ON", 4, "closed"),
    ("error:CYCLE_ON:1", 3, "closed"),
    ("corrupt:CYCLE_ON:version", 1, "closed"),
    ("close:CYCLE_OFF", 5, "closed"),
    ("stall:CYCLE_ON:300", 0, "carried on"),
]


@pytest.mark.parametrize(("spec", "exit_code", "did"), CASES)
def test_each_fault_kind_and_what_the_robot_did(box, tmp_path: Path, spec: str, exit_code: int, did: str) -> None:
    m, result = _through(box, tmp_path, [spec])
    assert result.exit_code == exit_code, result.reason
    doc = m.monitor_json()
    assert doc["faults"][0]["injected"] == 1
    inj = doc["injections"][0]
    assert inj["spec"] == spec and inj["kind"] == spec.split(":")[0]
    assert did in inj["summary"], inj
    # never blamed on the box: no box-side case fails, and the box's findings the fault caused are set aside
    failing = m.failing()
    assert not any(k.endswith("-box") for k in failing), failing
    case = next(c for c in m.summary()["cases"] if c["id"] == "MON-FAULT-1")
    assert case["verdict"] == "INFORMATIONAL" and spec in case["title"]
    # the pcap marks it
    pcap = sorted((tmp_path / "pcaps").glob("*.pcapng"))[0]
    comments = [c for _, c in pcapng_comments(pcap) if "INJECTED FAULT" in c]
    assert any(spec in c for c in comments), comments


def test_a_late_answer_within_time_out_is_waited_for(box, tmp_path: Path) -> None:
    m, result = _through(box, tmp_path, ["delay:CYCLE_ON:300"])
    on = next(e for e in result.timeline if "CYCLE_ON" in e.text and e.latency_ms is not None)
    assert on.latency_ms is not None and on.latency_ms >= 300  # a lower bound the sleep guarantees
    assert m.verdicts()["OBS-T1-box"] == "PASS"


def test_drop_every_nth_pose(box, tmp_path: Path) -> None:
    m, result = _through(box, tmp_path, ["drop:POSE,every=5"])
    doc = m.monitor_json()
    dropped = doc["faults"][0]["injected"]
    assert dropped == result.poses_sent // 5 and dropped >= 2
    assert result.poses_answered == result.poses_sent - dropped
    assert not any(k.endswith("-box") for k in m.failing()), m.failing()


def test_a_probability_fault_is_repeatable_with_its_seed(box, tmp_path: Path) -> None:
    picks = []
    for run in range(2):
        m, _ = _through(box, tmp_path / str(run), ["drop:POSE,p=0.3,seed=7,count=3"])
        picks.append([i["frame"] > 0 for i in m.monitor_json()["injections"]])
        assert m.monitor_json()["faults"][0]["injected"] == 3
    assert picks[0] == picks[1]
