"""``monitor --metrics``: the hub's counts in Prometheus's text exposition format (prometheus_client).

One :class:`HubCollector` per monitor, in its own :class:`~prometheus_client.CollectorRegistry`
(never the process-global one): each scrape reads the hub's counts at that moment, in
the event loop's thread (:func:`metrics_text` is called by the web server's handler), so
nothing is copied or locked between scrapes. The series (see docs/MONITOR.md):

==========================================  ====================================================
``isight_frames_total{direction,action}``   well-formed frames, ``robot_to_box`` / ``box_to_robot``
``isight_malformed_frames_total{direction}`` frames that break the format
``isight_answers_total{error_code}``        answers by error code (``0x0000`` ...)
``isight_answer_latency_seconds{kind}``     histogram: ``command`` (every request but poses),
                                            ``stream`` (poses)
``isight_findings_total{clause,side,verdict}`` findings filed (not PASS) since the start
``isight_alarms_active{kind}``              live alarms now (``box-silent``, ``stream-slow``,
                                            ``box-refused``)
``isight_alarms_total{kind}``               alarms raised since the start
``isight_connections_open``                 robot connections through the monitor now
``isight_connections_total``                robot connections since the start
``isight_upstream_failures_total``          connections the box refused or did not accept
``isight_sessions_total``                   sessions judged
``isight_ring_bytes``                       bytes of the pcapng ring on disk
``isight_stream_rate_hz``                   poses per second over the last tick
``isight_monitor_start_time_seconds``       when the monitor started (Unix time)
==========================================  ====================================================
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from prometheus_client import CollectorRegistry, generate_latest
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, HistogramMetricFamily, Metric
from prometheus_client.exposition import CONTENT_TYPE_LATEST

from ..protocol import Action, action_name
from .alarms import KINDS
from .hub import Hub
from .tally import Buckets

__all__ = ["CONTENT_TYPE_LATEST", "HubCollector", "metrics_text", "registry_for"]


def _name(action: int) -> str:
    return action_name(action)


def _histogram(name: str, doc: str, label: str, series: dict[str, Buckets]) -> HistogramMetricFamily:
    h = HistogramMetricFamily(name, doc, labels=[label])
    for value, b in series.items():
        h.add_metric([value], b.cumulative(), b.sum_s)
    return h


class HubCollector:
    """A custom collector: reads the hub at each scrape."""

    def __init__(self, hub: Hub, rate: Any = None) -> None:
        self.hub = hub
        self.rate = rate  # a callable giving the pose rate (the board's), or None

    def collect(self) -> Iterator[Metric]:
        hub = self.hub
        tally = hub.totals()
        frames = CounterMetricFamily("isight_frames", "well-formed iSight frames seen, by direction and action",
                                     labels=["direction", "action"])
        requests = dict(tally.requests)
        requests[int(Action.POSE)] = requests.get(int(Action.POSE), 0) + tally.poses
        answers = dict(tally.answers)
        answers[int(Action.POSE)] = answers.get(int(Action.POSE), 0) + tally.pose_answers
        for direction, counts in (("robot_to_box", requests), ("box_to_robot", answers)):
            for action, n in sorted(counts.items()):
                if n:
                    frames.add_metric([direction, _name(action)], n)
        yield frames
        bad = CounterMetricFamily("isight_malformed_frames", "frames that break the frame format, by direction",
                                  labels=["direction"])
        bad.add_metric(["robot_to_box"], tally.robot_errors)
        bad.add_metric(["box_to_robot"], tally.box_errors)
        yield bad
        codes = dict(tally.codes)
        codes[0] = codes.get(0, 0) + tally.pose_answers
        ans = CounterMetricFamily("isight_answers", "well-formed answers from the box, by error code",
                                  labels=["error_code"])
        for code, n in sorted(codes.items()):
            ans.add_metric([f"0x{code:04X}"], n)
        yield ans
        yield _histogram("isight_answer_latency_seconds", "time from a request to its answer, as the robot sees it",
                         "kind", {"command": hub.command_latency, "stream": hub.pose_latency})
        findings = CounterMetricFamily("isight_findings", "findings filed (not PASS), by clause, side and verdict",
                                       labels=["clause", "side", "verdict"])
        by: dict[tuple[str, str, str], int] = {}
        for cause in hub.findings.roots.causes.values():
            key = (cause.clause, cause.side, cause.verdict.value)
            by[key] = by.get(key, 0) + cause.count
        for key, n in sorted(by.items()):
            findings.add_metric(list(key), n)
        yield findings
        active = GaugeMetricFamily("isight_alarms_active", "live alarms now, by kind", labels=["kind"])
        raised = CounterMetricFamily("isight_alarms", "live alarms raised since the start, by kind", labels=["kind"])
        now = hub.alarms.by_kind()
        for kind in KINDS:
            active.add_metric([kind], now[kind])
            raised.add_metric([kind], hub.alarms.raised[kind])
        yield active
        yield raised
        yield GaugeMetricFamily("isight_connections_open", "robot connections through the monitor now",
                                value=len(hub.open))
        yield CounterMetricFamily("isight_connections", "robot connections since the start", value=hub.connections)
        yield CounterMetricFamily("isight_upstream_failures", "robot connections the box refused or did not accept",
                                  value=hub.upstream_failures)
        yield CounterMetricFamily("isight_sessions", "sessions judged", value=hub.ctx.stats.sessions)
        yield GaugeMetricFamily("isight_ring_bytes", "bytes of the pcapng ring on disk",
                                value=hub.ring.disk_bytes() if hub.ring is not None else 0)
        if self.rate is not None:
            yield GaugeMetricFamily("isight_stream_rate_hz", "poses per second, all streams, over the last tick",
                                    value=self.rate())
        yield GaugeMetricFamily("isight_monitor_start_time_seconds", "when the monitor started (Unix time)",
                                value=hub.started)


def registry_for(hub: Hub, rate: Any = None) -> CollectorRegistry:
    registry = CollectorRegistry(auto_describe=False)
    registry.register(HubCollector(hub, rate))
    return registry


def metrics_text(registry: CollectorRegistry) -> bytes:
    return generate_latest(registry)
