"""The monitor's live alarms, metrics and bind rule, sans-I/O (issue 26): no sockets, no threads."""

from __future__ import annotations

import re
from collections import deque
from pathlib import Path
from types import SimpleNamespace

import pytest

from conformance.analyze.analysis_context import AnalyzeConfig
from conformance.monitor.alarms import Alarms
from conformance.monitor.exposition import metrics_text, registry_for
from conformance.monitor.hub import Hub, MonitorSettings
from conformance.monitor.tally import Buckets
from conformance.monitor.webserve import check_bind, is_loopback
from conformance.protocol import Action

ROOT = Path(__file__).resolve().parents[2]


def _judge(queue=(), poses: int = 0, commands: dict | None = None) -> SimpleNamespace:  # type: ignore[no-untyped-def]
    return SimpleNamespace(queue=deque(queue), desync=None, label="conn 1 (a → b)", robot_counts=commands or {},
                           poses=poses)


def test_a_request_raises_box_silent_only_once_time_out_has_passed_and_its_late_answer_clears_it() -> None:
    alarms = Alarms(time_out_ms=5000, vision_time_out_ms=20000, rate_hz=50, rate_tolerance=0.1)
    req = (100.0, Action.CYCLE_ON, 41, 42, 0, b"", None, None, None)
    j = _judge([req], commands={1: 1})
    alarms.check([(1, j, True)], 104.9, {})
    assert not alarms.active
    alarms.check([(1, j, True)], 105.0, {})
    (alarm,) = alarms.active.values()
    assert (alarm.kind, alarm.clause, alarm.side, alarm.frame) == ("box-silent", "T1", "box", 42)
    alarms.check([(1, j, True)], 106.0, {})  # still the same request: one alarm, not two
    assert alarms.raised["box-silent"] == 1
    alarms.finding("T1", "box", "CYCLE_ON answered after 6012.4 ms", (42, 50), 106.1)
    assert not alarms.active and alarm.outcome.startswith("answered late") and alarm.cleared == 106.1


def test_a_result_request_waits_for_vision_time_out_and_a_faulted_connection_raises_nothing() -> None:
    alarms = Alarms(5000, 20000, 50, 0.1)
    j = _judge([(100.0, Action.VISION_RESULT, 9, 9, 0, b"", None, None, None)], commands={39: 1})
    alarms.check([(1, j, True)], 110.0, {})
    assert not alarms.active
    alarms.check([(1, j, True)], 110.0, {1: (5, 77)})  # a fault injected from frame 5 on
    alarms.check([(1, j, True)], 121.0, {1: (5, 77)})
    assert not alarms.active
    alarms.check([(1, j, True)], 121.0, {})
    assert [a.kind for a in alarms.active.values()] == ["box-silent"]


def test_the_connection_ending_clears_its_alarm() -> None:
    alarms = Alarms(1000, 1000, 50, 0.1)
    j = _judge([(0.0, Action.NONE, 1, 1, 0, b"", None, None, None)], commands={0: 1})
    alarms.check([(1, j, True)], 2.0, {})
    alarms.check([], 3.0, {})
    (alarm,) = alarms.cleared
    assert alarm.outcome == "the connection ended without the answer"


def test_a_stream_below_its_rate_alarms_and_clears() -> None:
    alarms = Alarms(5000, 5000, 50, 0.1)  # at least 45 poses/s over 2 s
    j = _judge()
    t = 0.0
    for _ in range(5):  # 20 poses/s for 2.5 s: below the bound, but not yet for a second
        j.poses += 10
        t += 0.5
        alarms.check([(3, j, True)], t, {})
    assert not alarms.active
    for _ in range(5):  # and on
        j.poses += 10
        t += 0.5
        alarms.check([(3, j, True)], t, {})
    (alarm,) = alarms.active.values()
    assert alarm.kind == "stream-slow" and alarm.side == "robot" and "20.0 poses/s" in alarm.text
    for _ in range(6):  # back at 50
        j.poses += 25
        t += 0.5
        alarms.check([(3, j, True)], t, {})
    assert not alarms.active and "back at 50.0" in alarm.outcome


def test_refused_until_accepted() -> None:
    alarms = Alarms(5000, 5000, 50, 0.1)
    alarms.refused(4, "the box refused the connection", 1.0)
    alarms.refused(5, "the box refused the connection", 2.0)
    assert alarms.raised["box-refused"] == 1 and len(alarms.active) == 1
    alarms.accepted(6, 3.0)
    assert not alarms.active and alarms.cleared[0].outcome == "the box accepted connection 6"


def test_buckets_are_cumulative_in_seconds() -> None:
    b = Buckets((0.001, 0.01, 1.0))
    for ms in (0.5, 1.0, 5.0, 2000.0):
        b.observe(ms)
    assert b.cumulative() == [("0.001", 2.0), ("0.01", 3.0), ("1.0", 3.0), ("+Inf", 4.0)]
    assert b.sum_s == pytest.approx(2.0065)


def _exported() -> str:
    hub = Hub(MonitorSettings(("127.0.0.1", 0), ("127.0.0.1", 9), AnalyzeConfig(), None))
    hub.command_latency.observe(2.0)
    hub.alarms.refused(1, "refused", 1.0)
    return metrics_text(registry_for(hub, lambda: 12.5)).decode()


def test_the_metrics_carry_every_series_the_docs_name() -> None:
    text = _exported()
    assert 'isight_alarms_active{kind="box-refused"} 1.0' in text
    assert 'isight_answer_latency_seconds_bucket{kind="command",le="0.0025"} 1.0' in text
    assert "isight_stream_rate_hz 12.5" in text
    names = set(re.findall(r"^# TYPE (\w+) ", text, re.M))
    documented = set(re.findall(r"`(isight_\w+)", (ROOT / "docs" / "MONITOR.md").read_text()))
    exported = names | {n + "_total" for n in names}
    assert documented and documented <= exported, documented - exported


@pytest.mark.parametrize("doc", ["docs/monitor/isight.rules.yml", "docs/monitor/grafana-dashboard.json"])
def test_the_rules_and_the_dashboard_use_only_exported_series(doc: str) -> None:
    text = _exported()
    names = set(re.findall(r"^# TYPE (\w+) ", text, re.M))
    exported = names | {n + s for n in names for s in ("_total", "_bucket", "_count", "_sum")}
    used = set(re.findall(r"\b(isight_[a-z_]+)", (ROOT / doc).read_text()))
    used -= {"isight_monitor"}  # the rule group's name
    assert used and used <= exported, used - exported


def test_only_loopback_without_allow_remote() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    check_bind("--http", "127.0.0.1", False)
    with pytest.raises(ValueError, match="--allow-remote"):
        check_bind("--http", "0.0.0.0", False)
    check_bind("--metrics", "0.0.0.0", True)
