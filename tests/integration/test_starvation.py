"""Timing on a loaded runner: kernel receive timestamps, the last look at the deadline, and the starvation gauge."""

from __future__ import annotations

import socket
import sys
import threading
import time
from collections.abc import Iterator

import pytest

from conformance.harness.client import Answer, Silence, TcpConnection
from conformance.harness.starvation import StarvationGauge, enable_rx_timestamps, recv_stamped
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.protocol import Action, Profile, encode, request
from conformance.protocol.constants import TransferType
from conformance.protocol.frames import Frame

ANSWER = encode(Frame(TransferType.BOX_TO_ROBOT, Action.NONE), Profile())


@pytest.fixture
def box() -> Iterator[tuple[Target, list[float]]]:
    """A box that answers each 14-byte NONE request after the delay at the head of ``delays`` (seconds)."""
    listener = socket.create_server(("127.0.0.1", 0))
    listener.settimeout(5)
    delays: list[float] = []

    def serve() -> None:
        conn, _ = listener.accept()
        with conn:
            conn.settimeout(5)
            while conn.recv(14) and delays:
                time.sleep(delays.pop(0))
                conn.sendall(ANSWER)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield Target("127.0.0.1", listener.getsockname()[1]), delays
    listener.close()
    thread.join(10)


def _conn(target: Target, time_out_s: float) -> TcpConnection:
    return TcpConnection(Transcript(case_id="t"), target, Profile(), "t", time_out_s).connect()


def test_a_kernel_stamp_is_the_arrival_not_the_read() -> None:
    server = socket.create_server(("127.0.0.1", 0))
    client = socket.create_connection(server.getsockname())
    peer, _ = server.accept()
    with server, client, peer:
        assert enable_rx_timestamps(client)
        sent = time.monotonic()
        peer.sendall(b"x")
        time.sleep(0.3)  # the reader is late
        data, stamp = recv_stamped(client)
        assert data == b"x" and stamp - sent < 0.2 < time.monotonic() - sent


def test_an_answer_that_came_in_time_counts_however_late_the_suite_looks(box: tuple[Target, list[float]]) -> None:
    target, delays = box
    delays.append(0.05)
    conn = _conn(target, 0.5)
    start = time.monotonic()
    assert conn.send(request(Action.NONE))
    time.sleep(0.8)  # the suite itself did not run until after time_out
    outcome = conn.next_outcome(0.0, since=start)  # the wait is over by the clock; one last look
    conn.close()
    assert isinstance(outcome, Answer) and outcome.latency_s < 0.4


def test_an_answer_after_time_out_is_still_silence(box: tuple[Target, list[float]]) -> None:
    target, delays = box
    delays.append(0.8)
    conn = _conn(target, 0.4)
    outcome = conn.request(request(Action.NONE), "NONE")
    late = conn.next_outcome(2.0)  # it comes later, and is read then
    conn.close()
    assert isinstance(outcome, Silence) and isinstance(late, Answer)


def test_the_gauge_sees_the_process_kept_from_running() -> None:
    gauge = StarvationGauge(0.002).start()
    try:
        time.sleep(0.05)
        previous = sys.getswitchinterval()
        sys.setswitchinterval(1.0)  # this thread keeps the interpreter: the gauge's timer cannot run
        try:
            start = time.monotonic()
            while time.monotonic() - start < 0.25:
                pass
        finally:
            sys.setswitchinterval(previous)
        time.sleep(0.05)
        assert gauge.worst_ms(start, time.monotonic()) >= 100.0
        assert gauge.worst_ms(0.0, start - 0.5) < 100.0
    finally:
        gauge.stop()
