"""The background pose stream against the bundled box."""

from __future__ import annotations

from conformance.endpoints.behaviour import BoxConfig
from conformance.endpoints.loop import BoxThread
from conformance.harness.client import TcpConnection
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.runtime.settings import SuiteSettings
from conformance.suite.pose_stream import PoseStream


def test_pose_stream_against_slow_bundled_box() -> None:
    with BoxThread(BoxConfig(latency_ms=20)) as box:
        conn = TcpConnection(Transcript(), Target("127.0.0.1", box.tcp_port), SuiteSettings().profile, "stream").connect()
        result = PoseStream(conn, 100.0, 0.5, 5.0).start().wait()
        conn.close()
    assert (result.sent, result.answered, result.lost, result.failed) == (50, 50, 0, False)
    assert min(result.latencies_ms) >= 19.0 and result.max_send_lag_ms < 100
