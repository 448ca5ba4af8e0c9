"""S: state and sequences (canonical session, CycleOn/Off, concurrency, connection cycles, pipelining)."""

from __future__ import annotations

import socket
import time

from conformance.harness.client import Answer, Closed, Outcome, Silence, TcpConnection
from conformance.harness.transcript import Kind
from conformance.protocol import Action, Frame, pose_blocks, request, tolerance_blocks
from conformance.suite.context import CaseContext
from conformance.suite.judge import CLOSED, Inconclusive, answered, check, fail
from conformance.suite.record import case
from conformance.suite.sequence import PoseStream, judge_stream, latency_figures, percentile
from conformance.suite.verdicts import Level

HOME = (800.0, -100.0, 300.0, 180.0, 0.0, 0.0)


def _frame(isight: CaseContext, action: Action) -> Frame:
    first = isight.profile.first_index
    if action in (Action.POSE, Action.REGISTER_POSE):
        return request(action, pose_blocks([HOME], first))
    if action is Action.TOLERANCE:
        return request(action, tolerance_blocks([0.5], first))
    return request(action)


def _ask(isight: CaseContext, conn: TcpConnection, action: Action, errors: list[int] | None = None,
         what: str = "A1: a well-formed request is answered") -> Answer:
    """One request on ``conn``; MUST be answered (with an error code in ``errors``); latency recorded."""
    frame = _frame(isight, action)
    sent = conn.codec.encode(frame)
    outcome = conn.request(sent, f"{action.name} request")
    if isinstance(outcome, Answer):
        isight.latencies_ms.append(outcome.latency_s * 1000)
    check(outcome, answered(action, errors), Level.MUST, what, sent=sent)
    assert isinstance(outcome, Answer)
    return outcome


def _cycle_on(isight: CaseContext, conn: TcpConnection) -> None:
    """CycleOn: 0000, or 0001 (box not ready) which makes the rest INCONCLUSIVE (S2)."""
    outcome = _ask(isight, conn, Action.CYCLE_ON, [0, 1], "S2: CycleOn is answered 0000, or 0001 when not ready")
    if outcome.frame.error_code == 1:
        _ask(isight, conn, Action.CYCLE_OFF, None)
        raise Inconclusive("CycleOn answered 0001 (box not ready): the rest of the cycle cannot be judged (S2)")


def _stream(isight: CaseContext, label: str = "stream") -> TcpConnection:
    return isight.connect(label, target=isight.session.stream_target())


def _p50_latency(isight: CaseContext, conn: TcpConnection, count: int, what: str, gap_s: float = 0.0) -> list[float]:
    out = []
    for _ in range(count):
        out.append(_ask(isight, conn, Action.NONE, [0], what).latency_s * 1000)
        if gap_s:
            time.sleep(gap_s)
    return out


def _not_delayed(base: list[float], during: list[float], what: str) -> None:
    b, d = percentile(base, 50), percentile(during, 50)
    limit = b + max(100.0, 5 * b)
    if d > limit:
        raise fail(Level.MUST, what, f"command p50 ≤ {limit:.1f} ms (baseline p50 {b:.1f} ms + max(100 ms, 5×))",
                   f"command p50 {d:.1f} ms (max {max(during):.1f} ms)")


@case("S1-01", ["S1", "S2", "S3", "A1", "T1"], Level.MUST, "The canonical session completes with every answer 0000",
      "every answer 0000 within time_out and every streamed pose answered 0000; CycleOn 0001 → INCONCLUSIVE")
def test_canonical_session(isight: CaseContext) -> None:
    command = isight.connect("command")
    for action in (Action.NONE, Action.TOLERANCE, Action.REGISTER_POSE):
        _ask(isight, command, action, [0], f"S1: configure step {action.name} is answered 0000")
    stream = PoseStream(_stream(isight), isight.profile.pose_rate_hz, None, isight.time_out_s,
                        first_index=isight.profile.first_index).start()
    try:
        time.sleep(0.1)
        _cycle_on(isight, command)
        time.sleep(0.5)  # the primer trajectory; poses keep flowing
        _ask(isight, command, Action.CYCLE_OFF, [0], "S1: CycleOff is answered 0000 on a ready box")
    finally:
        result = stream.stop()
    isight.latencies_ms.extend(result.latencies_ms)
    isight.details["stream"] = result.figures()
    judge_stream(result, Level.MUST, "S1/S6: the stream of the canonical session")
    stream.conn.close("Send_Pos_Off")
    command.close("disconnect")


@case("S2-01", ["S2", "A1"], Level.MUST, "CycleOn is answered 0000, or 0001 when the box is not ready",
      "CycleOn answered with 0000 or 0001 (0001 is reported)")
def test_cycle_on(isight: CaseContext) -> None:
    conn = isight.connect()
    code = _ask(isight, conn, Action.CYCLE_ON, [0, 1], "S2: CycleOn is answered 0000, or 0001 when not ready").frame.error_code
    _ask(isight, conn, Action.CYCLE_OFF)
    if code == 1:
        isight.inform("CycleOn answered 0001: the box says it is not ready; cycle cases are INCONCLUSIVE")


@case("S3-01", ["S3"], Level.MUST, "Poses before CycleOn are answered 0000",
      "after a CycleOff (any answer), poses are answered 0000 [decision]")
def test_poses_before_cycle_on(isight: CaseContext) -> None:
    conn = isight.connect()
    _ask(isight, conn, Action.CYCLE_OFF)  # no cycle on, whatever the box says
    for _ in range(5):
        _ask(isight, conn, Action.POSE, [0], "S3: poses are answered 0000 whether or not a cycle is on")


@case("S3-02", ["S3"], Level.MUST, "Poses after CycleOff are answered 0000",
      "after CycleOn and CycleOff, poses are answered 0000 [decision]")
def test_poses_after_cycle_off(isight: CaseContext) -> None:
    conn = isight.connect()
    _ask(isight, conn, Action.CYCLE_ON, [0, 1], "S2: CycleOn is answered 0000, or 0001 when not ready")
    _ask(isight, conn, Action.CYCLE_OFF)
    for _ in range(5):
        _ask(isight, conn, Action.POSE, [0], "S3: poses are answered 0000 whether or not a cycle is on")


@case("S3-03", ["S3", "A1"], Level.MUST, "CycleOff without CycleOn is answered (0000 or an error: MAY)",
      "answered; what it answered is INFORMATIONAL")
def test_cycle_off_without_cycle_on(isight: CaseContext) -> None:
    conn = isight.connect()
    _ask(isight, conn, Action.CYCLE_OFF)
    code = _ask(isight, conn, Action.CYCLE_OFF).frame.error_code
    isight.inform(f"CycleOff with no cycle on was answered {code:04x}")


@case("S3-04", ["S3", "A1"], Level.MUST, "CycleOn twice is answered (0000 or an error: MAY)",
      "answered; what it answered is INFORMATIONAL")
def test_cycle_on_twice(isight: CaseContext) -> None:
    conn = isight.connect()
    _cycle_on(isight, conn)
    code = _ask(isight, conn, Action.CYCLE_ON).frame.error_code
    _ask(isight, conn, Action.CYCLE_OFF)
    isight.inform(f"a second CycleOn while a cycle is on was answered {code:04x}")


@case("S4-01", ["S4", "T1"], Level.MUST, "A silent stream connection does not delay command answers",
      "while the stream holds half a frame and sends nothing, command answers come within time_out and "
      "their p50 stays ≤ baseline p50 + max(100 ms, 5×)")
def test_silent_stream(isight: CaseContext) -> None:
    base_conn = isight.connect("command (baseline)")
    base = _p50_latency(isight, base_conn, 10, "A1: NONE is answered 0000")
    base_conn.close()
    stream = _stream(isight, "stream (stalled)")
    half = stream.codec.encode(_frame(isight, Action.POSE))[:19]
    stream.send(half, "half a pose frame, then nothing")
    try:
        command = isight.connect("command")
        during = _p50_latency(isight, command, 10, "S4: a silent stream connection never delays the command connection")
    finally:
        stream.abort("release the stalled stream")
        isight.close_all()  # before the liveness check that may follow
    isight.details.update(baseline=latency_figures(base), during_stall=latency_figures(during))
    _not_delayed(base, during, "S4: a silent stream connection never delays answers on the command connection")


@case("S4-02", ["S4", "S6", "T1"], Level.MUST, "A busy stream does not delay command answers",
      "with poses flowing at the profile rate, command answers come within time_out, p50 ≤ baseline p50 + "
      "max(100 ms, 5×), and every pose is answered")
def test_busy_stream(isight: CaseContext) -> None:
    base_conn = isight.connect("command (baseline)")
    base = _p50_latency(isight, base_conn, 10, "A1: NONE is answered 0000")
    base_conn.close()
    stream = PoseStream(_stream(isight), isight.profile.pose_rate_hz, None, isight.time_out_s,
                        first_index=isight.profile.first_index).start()
    try:
        command = isight.connect("command")
        during = _p50_latency(isight, command, 20, "S4: the command connection is served while the stream is busy", 0.02)
    finally:
        result = stream.stop()
        isight.close_all()  # before the liveness check that may follow
    isight.details.update(baseline=latency_figures(base), during_stream=latency_figures(during), stream=result.figures())
    judge_stream(result, Level.MUST, "S4/S6: the stream served next to the command connection")
    _not_delayed(base, during, "S4: a busy stream never delays answers on the command connection")


@case("S5-01", ["S5", "T1"], Level.MUST, "100 connect/disconnect cycles leave the box as responsive as the first",
      "every connect accepted; afterwards NONE on a fresh connection answered with p50 ≤ before p50 + max(50 ms, 5×)")
def test_connect_cycles(isight: CaseContext) -> None:
    def fresh(n: int) -> list[float]:
        out = []
        for _ in range(n):
            conn = isight.connect("fresh")
            out.append(_ask(isight, conn, Action.NONE, [0], "S5: a fresh connection is answered").latency_s * 1000)
            conn.close()
        return out

    before = fresh(5)
    for i in range(100):
        conn = isight.try_connect(f"cycle {i + 1}")
        if conn is None:
            raise fail(Level.MUST, "S5: after the robot closes a connection the box frees it",
                       "100 connections accepted one after another", f"connect #{i + 1} failed")
        if i % 2:
            _ask(isight, conn, Action.NONE, [0], "S5: every cycle's connection is served")
        conn.close()
    after = fresh(5)
    b, a = percentile(before, 50), percentile(after, 50)
    isight.details.update(before=latency_figures(before), after=latency_figures(after))
    limit = b + max(50.0, 5 * b)
    if a > limit:
        raise fail(Level.MUST, "S5: a hundred connect/disconnect cycles leave the box as responsive as the first",
                   f"p50 ≤ {limit:.1f} ms (before: {b:.1f} ms)", f"p50 {a:.1f} ms after 100 cycles")


@case("S5-02", ["S5"], Level.MUST, "After the robot closes, the box closes its side",
      "after our FIN (half-close, still reading) the box's FIN or RST arrives within time_out")
def test_box_closes_its_side(isight: CaseContext) -> None:
    conn = isight.connect()
    _ask(isight, conn, Action.NONE, [0], "A1: NONE is answered 0000")
    assert conn.sock is not None
    conn.sock.shutdown(socket.SHUT_WR)
    isight.transcript.add(conn.conn_id, Kind.CLOSE, note="robot closes its side (FIN) and keeps reading (S5)")
    deadline = time.monotonic() + isight.time_out_s
    outcome: Outcome = Silence(0.0)
    while (left := deadline - time.monotonic()) > 0:
        outcome = conn.next_outcome(left)
        if isinstance(outcome, (Closed, Silence)):
            break
    conn.close("release the socket")
    check(outcome, CLOSED, Level.MUST, "S5: after the robot closes a connection the box closes its side")


@case("S6-01", ["S6", "A1"], Level.MUST, "200 pipelined requests are all answered, in order",
      "200 requests sent without waiting (poses, with RegisterPose and Tolerance among them) get 200 answers "
      "echoing each request's action in order, each 0000")
def test_pipelined(isight: CaseContext) -> None:
    conn = _stream(isight)
    actions = [Action.REGISTER_POSE if i % 10 == 9 else Action.TOLERANCE if i % 25 == 12 else Action.POSE
               for i in range(200)]
    frames = [conn.codec.encode(_frame(isight, a)) for a in actions]
    start = time.monotonic()
    for i, data in enumerate(frames):
        if not conn.send(data, f"request {i + 1}/200 ({actions[i].name}), not waiting"):
            break
    for i, (action, data) in enumerate(zip(actions, frames)):
        outcome = conn.next_outcome(since=start)
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)
        check(outcome, answered(action, [0]), Level.MUST,
              f"S6/A1: request {i + 1} of 200 pipelined is answered, in request order", sent=data)
    isight.details["latency"] = latency_figures(isight.latencies_ms)
