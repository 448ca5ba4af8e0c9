"""``run --lanes auto``'s probe against small loopback boxes: lanes only for a slow box that serves two
connections at once."""

from __future__ import annotations

import socket
import time
from collections.abc import Callable

import pytest

from conformance.harness.concurrency import probe_lanes
from conformance.harness.target import Target
from conformance.protocol import Profile, ProtocolError, StreamDecoder, TransferType, answer, encode
from tests.boxes import ScriptedBox
from tests.integration.test_quiet import OneAtATime

pytestmark = pytest.mark.integration
P = Profile(time_out_ms=1500)


def answering_after(delay_s: float) -> Callable[[socket.socket], None]:
    def handler(conn: socket.socket) -> None:
        conn.settimeout(10)
        decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
        while data := conn.recv(65536):
            for event in decoder.feed(data):
                if not isinstance(event, ProtocolError):
                    time.sleep(delay_s)
                    conn.sendall(encode(answer(event.action)))
    return handler


def test_a_slow_box_serving_two_connections_gets_lanes() -> None:
    with ScriptedBox(answering_after(0.05)) as box:
        probe = probe_lanes(Target("127.0.0.1", box.port), P, P.time_out_s)
    assert probe.concurrent and probe.round_trip_ms is not None and probe.round_trip_ms >= 50
    assert probe.lanes(3) == 3 and "two connections at once" in probe.why


def test_a_box_serving_one_connection_at_a_time_runs_one_case_at_a_time() -> None:
    with OneAtATime() as box:
        probe = probe_lanes(Target("127.0.0.1", box.port), P, P.time_out_s)
    assert not probe.concurrent and probe.lanes(3) == 1
    assert "second connection was not answered" in probe.why


def test_a_closed_port_gets_no_lanes_and_no_exception() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound, not listening: refused
    probe = probe_lanes(Target("127.0.0.1", port), P, P.time_out_s)
    assert not probe.concurrent and probe.lanes(3) == 1
