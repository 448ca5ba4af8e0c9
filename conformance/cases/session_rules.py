"""S: state and sequences (canonical session, CycleOn/Off, concurrency, connection cycles, pipelining)."""

from __future__ import annotations

import socket
import time

from conformance.protocol import Action, ErrorCode, Frame, request
from conformance.protocol.answers import CANONICAL_CODES, Cycle
from conformance.suite import (
    ANSWERED,
    CLOSED,
    Answer,
    CaseContext,
    Closed,
    Kind,
    Level,
    Outcome,
    PoseStream,
    Requirement,
    Silence,
    TcpConnection,
    answered,
    answered_allowed,
    case,
    latency_figures,
    percentile,
)

# -- the family's helpers: Helpers of the S cases (conformance/cases/session_rules.py): the session's requirements, asking and cycling, the stream, latency comparisons.
HOME = (800.0, -100.0, 300.0, 180.0, 0.0, 0.0)

ON, OFF, NONE, POSE = Action.CYCLE_ON, Action.CYCLE_OFF, Action.NONE, Action.POSE

NONE_0 = Requirement(("A1",), "NONE is answered 0000", accept=answered_allowed(NONE))

CYCLE_ON = Requirement(("S2",), "CycleOn is answered 0000, or 0001 when not ready", accept=answered_allowed(ON, Cycle.IDLE))

READY = Requirement(("S2",), "the box is ready for a cycle", inconclusive=answered(ON, [ErrorCode.NOT_READY]),
                    inconclusive_text="CycleOn answered 0001 (box not ready): the rest of the cycle cannot be judged (S2)")

POSES_0 = Requirement(("S3",), "poses are answered 0000 whether or not a cycle is on", accept=answered_allowed(POSE))


def step_frame(isight: CaseContext, action: Action) -> Frame:
    if action in (Action.POSE, Action.REGISTER_POSE):
        return request(action, isight.codec.pose_blocks([HOME]))
    if action is Action.TOLERANCE:
        return request(action, isight.codec.tolerance_blocks([0.5]))
    return request(action)


def ask(isight: CaseContext, conn: TcpConnection, action: Action, check: str = "answered") -> Answer:
    """One request on ``conn``, judged by the case's requirement ``check``; latency recorded."""
    frame = step_frame(isight, action)
    sent = conn.codec.encode(frame)
    outcome = conn.request(sent, f"{action.name} request")
    if isinstance(outcome, Answer):
        isight.latencies_ms.append(outcome.latency_s * 1000)
    isight.judge(outcome, check, sent=sent, action=action)
    assert isinstance(outcome, Answer)
    return outcome


def cycle_on(isight: CaseContext, conn: TcpConnection) -> None:
    """CycleOn: 0000, or 0001 (box not ready) which makes the rest INCONCLUSIVE (S2), after a CycleOff."""
    outcome = ask(isight, conn, ON, "cycle-on")
    if outcome.frame.error_code == 1:
        ask(isight, conn, OFF)  # leave the box idle
    isight.judge(outcome, "ready")


def open_stream(isight: CaseContext, label: str = "stream") -> TcpConnection:
    return isight.connect(label, target=isight.session.stream_target())


def p50_latency(isight: CaseContext, conn: TcpConnection, count: int, check: str, gap_s: float = 0.0) -> list[float]:
    out = []
    for _ in range(count):
        out.append(ask(isight, conn, NONE, check).latency_s * 1000)
        if gap_s:
            time.sleep(gap_s)
    return out


def not_delayed(isight: CaseContext, base: list[float], during: list[float]) -> None:
    b, d = percentile(base, 50), percentile(during, 50)
    limit = b + max(100.0, 5 * b)
    if d > limit:
        raise isight.broken(expected=f"command p50 ≤ {limit:.1f} ms (baseline p50 {b:.1f} ms + max(100 ms, 5×))",
                            observed=f"command p50 {d:.1f} ms (max {max(during):.1f} ms)")


# -- the cases

@case("S1-01", ["S1", "S2", "S3", "A1", "T1"], Level.MUST, "The canonical session completes with every answer 0000",
      "every answer 0000 within time_out and every streamed pose answered 0000; CycleOn 0001 → INCONCLUSIVE",
      checks={"answered": ANSWERED, "cycle-on": CYCLE_ON, "ready": READY,
              "configure": Requirement(("S1",), "configure step {action.name} is answered 0000",
                                       accept=lambda action, **_: answered_allowed(action)),
              "cycle-off": Requirement(("S1",), "CycleOff is answered 0000 on a ready box", accept=answered(OFF, CANONICAL_CODES)),
              "stream": Requirement(("S1", "S6"), "the stream of the canonical session")})
def test_canonical_session(isight: CaseContext) -> None:
    command = isight.connect("command")
    for action in (Action.NONE, Action.TOLERANCE, Action.REGISTER_POSE):
        ask(isight, command, action, "configure")
    stream = PoseStream(open_stream(isight), isight.profile.pose_rate_hz, None, isight.time_out_s).start()
    try:
        time.sleep(0.1)
        cycle_on(isight, command)
        time.sleep(0.5)  # the primer trajectory; poses keep flowing
        ask(isight, command, OFF, "cycle-off")
    finally:
        result = stream.stop()
    isight.latencies_ms.extend(result.latencies_ms)
    isight.details["stream"] = result.figures()
    isight.judge_stream(result)
    stream.conn.close("Send_Pos_Off")
    command.close("disconnect")


@case("S2-01", ["S2", "A1"], Level.MUST, "CycleOn is answered 0000, or 0001 when the box is not ready",
      "CycleOn answered with 0000 or 0001 (0001 is reported)",
      checks={"answered": ANSWERED,
              "cycle-on": Requirement(CYCLE_ON.clauses, CYCLE_ON.text, accept=CYCLE_ON.accept, informational=answered(ON, [ErrorCode.NOT_READY]),
                                      informational_text="CycleOn answered 0001: the box says it is not ready; cycle "
                                                         "cases are INCONCLUSIVE")})
def test_cycle_on(isight: CaseContext) -> None:
    conn = isight.connect()
    ask(isight, conn, ON, "cycle-on")
    ask(isight, conn, OFF)


@case("S3-01", ["S3"], Level.MUST, "Poses before CycleOn are answered 0000",
      "after a CycleOff (any answer), poses are answered 0000 [decision]",
      checks={"answered": ANSWERED, "poses": POSES_0})
def test_poses_before_cycle_on(isight: CaseContext) -> None:
    conn = isight.connect()
    ask(isight, conn, OFF)  # no cycle on, whatever the box says
    for _ in range(5):
        ask(isight, conn, POSE, "poses")


@case("S3-02", ["S3"], Level.MUST, "Poses after CycleOff are answered 0000",
      "after CycleOn and CycleOff, poses are answered 0000 [decision]",
      checks={"answered": ANSWERED, "cycle-on": CYCLE_ON, "poses": POSES_0})
def test_poses_after_cycle_off(isight: CaseContext) -> None:
    conn = isight.connect()
    ask(isight, conn, ON, "cycle-on")
    ask(isight, conn, OFF)
    for _ in range(5):
        ask(isight, conn, POSE, "poses")


@case("S3-03", ["S3", "A1"], Level.MUST, "CycleOff without CycleOn is answered (0000 or an error: MAY)",
      "answered; what it answered is INFORMATIONAL",
      checks={"answered": ANSWERED,
              "again": Requirement(("A1",), "CycleOff with no cycle on is answered (0000 or an error: MAY, S3)",
                                   accept=answered_allowed(OFF, Cycle.IDLE), informational=answered(OFF),
                                   informational_text="CycleOff with no cycle on: the box {outcome}")})
def test_cycle_off_without_cycle_on(isight: CaseContext) -> None:
    conn = isight.connect()
    ask(isight, conn, OFF)
    ask(isight, conn, OFF, "again")


@case("S3-04", ["S3", "A1"], Level.MUST, "CycleOn twice is answered (0000 or an error: MAY)",
      "answered; what it answered is INFORMATIONAL",
      checks={"answered": ANSWERED, "cycle-on": CYCLE_ON, "ready": READY,
              "again": Requirement(("A1",), "a second CycleOn is answered (0000 or an error: MAY, S3)", accept=answered_allowed(ON, Cycle.ON),
                                   informational=answered(ON),
                                   informational_text="a second CycleOn while a cycle is on: the box {outcome}")})
def test_cycle_on_twice(isight: CaseContext) -> None:
    conn = isight.connect()
    cycle_on(isight, conn)
    ask(isight, conn, ON, "again")
    ask(isight, conn, OFF)


@case("S4-01", ["S4", "T1"], Level.MUST, "A silent stream connection does not delay command answers",
      "while the stream holds half a frame and sends nothing, command answers come within time_out and "
      "their p50 stays ≤ baseline p50 + max(100 ms, 5×)",
      checks={"none": NONE_0,
              "during": Requirement(("S4",), "a silent stream connection never delays the command connection",
                                    accept=answered_allowed(NONE)),
              "": Requirement(("S4",), "a silent stream connection never delays answers on the command connection")})
def test_silent_stream(isight: CaseContext) -> None:
    base_conn = isight.connect("command (baseline)")
    base = p50_latency(isight, base_conn, 10, "none")
    base_conn.close()
    stream = open_stream(isight, "stream (stalled)")
    half = stream.codec.encode(step_frame(isight, Action.POSE))[:19]
    stream.send(half, "half a pose frame, then nothing")
    try:
        command = isight.connect("command")
        during = p50_latency(isight, command, 10, "during")
    finally:
        stream.abort("release the stalled stream")
        isight.close_all()  # before the liveness check that may follow
    isight.details.update(baseline=latency_figures(base), during_stall=latency_figures(during))
    not_delayed(isight, base, during)


@case("S4-02", ["S4", "S6", "T1"], Level.MUST, "A busy stream does not delay command answers",
      "with poses flowing at the profile rate, command answers come within time_out, p50 ≤ baseline p50 + "
      "max(100 ms, 5×), and every pose is answered",
      checks={"none": NONE_0,
              "during": Requirement(("S4",), "the command connection is served while the stream is busy",
                                    accept=answered_allowed(NONE)),
              "stream": Requirement(("S4", "S6"), "the stream served next to the command connection"),
              "": Requirement(("S4",), "a busy stream never delays answers on the command connection")})
def test_busy_stream(isight: CaseContext) -> None:
    base_conn = isight.connect("command (baseline)")
    base = p50_latency(isight, base_conn, 10, "none")
    base_conn.close()
    stream = PoseStream(open_stream(isight), isight.profile.pose_rate_hz, None, isight.time_out_s).start()
    try:
        command = isight.connect("command")
        during = p50_latency(isight, command, 20, "during", 0.02)
    finally:
        result = stream.stop()
        isight.close_all()  # before the liveness check that may follow
    isight.details.update(baseline=latency_figures(base), during_stream=latency_figures(during), stream=result.figures())
    isight.judge_stream(result)
    not_delayed(isight, base, during)


@case("S5-01", ["S5", "T1"], Level.MUST, "100 connect/disconnect cycles leave the box as responsive as the first",
      "every connect accepted; afterwards NONE on a fresh connection answered with p50 ≤ before p50 + max(50 ms, 5×)",
      checks={"fresh": Requirement(("S5",), "a fresh connection is answered", accept=answered_allowed(NONE)),
              "cycle": Requirement(("S5",), "every cycle's connection is served", accept=answered_allowed(NONE)),
              "freed": Requirement(("S5",), "after the robot closes a connection the box frees it"),
              "": Requirement(("S5",), "a hundred connect/disconnect cycles leave the box as responsive as the first")})
def test_connect_cycles(isight: CaseContext) -> None:
    def fresh(n: int) -> list[float]:
        out = []
        for _ in range(n):
            conn = isight.connect("fresh")
            out.append(ask(isight, conn, NONE, "fresh").latency_s * 1000)
            conn.close()
        return out

    before = fresh(5)
    for i in range(100):
        conn = isight.try_connect(f"cycle {i + 1}")
        if conn is None:
            raise isight.broken("freed", expected="100 connections accepted one after another",
                                observed=f"connect #{i + 1} failed")
        if i % 2:
            ask(isight, conn, NONE, "cycle")
        conn.close()
    after = fresh(5)
    b, a = percentile(before, 50), percentile(after, 50)
    isight.details.update(before=latency_figures(before), after=latency_figures(after))
    limit = b + max(50.0, 5 * b)
    if a > limit:
        raise isight.broken(expected=f"p50 ≤ {limit:.1f} ms (before: {b:.1f} ms)",
                            observed=f"p50 {a:.1f} ms after 100 cycles")


@case("S5-02", ["S5"], Level.MUST, "After the robot closes, the box closes its side",
      "after our FIN (half-close, still reading) the box's FIN or RST arrives within time_out",
      checks={"none": NONE_0, "": Requirement(("S5",), "after the robot closes a connection the box closes its side",
                                              accept=CLOSED)})
def test_box_closes_its_side(isight: CaseContext) -> None:
    conn = isight.connect()
    ask(isight, conn, NONE, "none")
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
    isight.judge(outcome, sent=b"")


@case("S6-01", ["S6", "A1"], Level.MUST, "200 pipelined requests are all answered, in order",
      "200 requests sent without waiting (poses, with RegisterPose and Tolerance among them) get 200 answers "
      "echoing each request's action in order, each 0000",
      checks={"": Requirement(("S6", "A1"), "request {n} of 200 pipelined is answered, in request order",
                              accept=lambda action, **_: answered_allowed(action))})
def test_pipelined(isight: CaseContext) -> None:
    conn = open_stream(isight)
    actions = [Action.REGISTER_POSE if i % 10 == 9 else Action.TOLERANCE if i % 25 == 12 else Action.POSE
               for i in range(200)]
    frames = [conn.codec.encode(step_frame(isight, a)) for a in actions]
    start = time.monotonic()
    for i, data in enumerate(frames):
        if not conn.send(data, f"request {i + 1}/200 ({actions[i].name}), not waiting"):
            break
    for i, (action, data) in enumerate(zip(actions, frames)):
        outcome = conn.next_outcome(since=start)
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)
        isight.judge(outcome, sent=data, n=i + 1, action=action)
    isight.details["latency"] = latency_figures(isight.latencies_ms)
