"""Canonical-order tracking (S1/E4), the cut, and awaited answers, on hand-built sessions.

``Fake`` builds a SessionRecord the way the listener would (transcript events with
chosen times, the box's exchanges), so every judgement here is exact and timeless.
The other certify tests import it.
"""

from __future__ import annotations

import pytest

from conformance.harness.transcript import ConnectionInfo, Endpoint, Kind, Transcript, WireEvent
from conformance.observed.connections import BY_BOX, BY_ROBOT, BY_SUITE, ConnRecord, Exchange, SessionRecord
from conformance.observed.session import (
    E4_STEPS,
    S1_STEPS,
    awaited,
    build_view,
    judge_order,
    observe_steps,
)
from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    ErrorCode,
    answer,
    encode,
    pose_blocks,
    request,
    tolerance_blocks,
    value_blocks,
)

LOCAL = Endpoint("127.0.0.1", 9004)
POSE = encode(request(Action.POSE, pose_blocks([(800.0, 10.0, 300.0, 180.0, 1.0, 0.0)])))


def frame(action: Action, value: int | None = None) -> bytes:
    blocks = value_blocks([value]) if value is not None else ()
    return encode(request(action, blocks))


class Fake:
    """A session record built by hand."""

    def __init__(self, number: int = 1) -> None:
        self.session = SessionRecord(number, 0.0)
        self._offsets: dict[int, int] = {}

    def conn(self, t_open: float, transport: str = "tcp") -> ConnRecord:
        number = len(self.session.conns) + 1
        peer = Endpoint("127.0.0.1", 40000 + number)
        tr = Transcript(case_id=f"fake-{number}")
        tr.connections[1] = ConnectionInfo(1, transport, LOCAL, peer)
        tr.events.append(WireEvent(t_open, 1, Kind.CONNECT, note="accepted from robot"))
        rec = ConnRecord(number, transport, tr, LOCAL, peer, t_open)
        self.session.conns.append(rec)
        self._offsets[number] = 0
        return rec

    def send(self, conn: ConnRecord, t: float, data: bytes, *, error_code: int = 0, value: int | None = None,
             answered: float | None = -1.0, request_like: bool = True) -> None:
        """The robot sends ``data`` (one frame, or garbage with request_like=False) at ``t``;
        the box answers at ``answered`` (default at once; None: never)."""
        self._add(conn, WireEvent(t, 1, Kind.RECV, data))
        offset = self._offsets[conn.number] if conn.transport == "tcp" else len(conn.exchanges)
        self._offsets[conn.number] += len(data)
        action = data[5] if request_like and data[5] in {a.value for a in Action} else None  # A5: not a request
        if action is not None:
            conn.actions.append(action)
        t_answer = t + 0.0001 if answered == -1.0 else answered
        if action is None or t_answer is None:
            conn.exchanges.append(Exchange(offset, t, action, "silent" if action is None else "ok"))
            return
        blocks = value_blocks([value]) if value is not None else ()
        out = encode(answer(Action(action), error_code, blocks))
        conn.exchanges.append(Exchange(offset, t, action, "ok", out, f"answer {action:#x}", error_code, value, t_answer))
        self._add(conn, WireEvent(t_answer, 1, Kind.SEND, out))

    @staticmethod
    def _add(conn: ConnRecord, event: WireEvent) -> None:
        """Events in time order, as a listener records them (whatever order a test adds them in)."""
        conn.transcript.events.append(event)
        conn.transcript.events.sort(key=lambda e: e.t)

    def close(self, conn: ConnRecord, t: float, by: str = BY_ROBOT, note: str = "") -> None:
        kind = Kind.PEER_CLOSE if by == BY_ROBOT else Kind.CLOSE
        self._add(conn, WireEvent(t, 1, kind, note=note))
        conn.t_close, conn.closed_by, conn.close_note = t, by, note


def canonical(extension: bool = False, *, cycle_on: float = 0.2, cycle_off: float = 0.8, stream_close: float = 0.9,
              cmd_close: float = 2.0, poses: tuple[float, float] = (0.02, 0.88)) -> tuple[Fake, ConnRecord, ConnRecord]:
    """A clean session: command at 0, ProgIdx at 0.005 (E4), stream at 0.01, poses every 20 ms."""
    fake = Fake()
    cmd = fake.conn(0.0)
    if extension:
        fake.send(cmd, 0.005, frame(Action.PROG_IDX, 1), value=1)
    stream = fake.conn(0.01)
    t = poses[0]
    while t <= poses[1] + 1e-9:
        fake.send(stream, t, POSE)
        t = round(t + 0.02, 6)
    fake.send(cmd, cycle_on, frame(Action.CYCLE_ON))
    fake.send(cmd, cycle_off, frame(Action.CYCLE_OFF))
    fake.close(stream, stream_close)
    if extension:
        fake.send(cmd, 1.9, frame(Action.VISION_RESULT), value=1)
    fake.close(cmd, cmd_close)
    fake.session.t_end = cmd_close
    return fake, cmd, stream


def order(fake: Fake, extension: bool = False):
    return judge_order(build_view(fake.session, DEFAULT_PROFILE), extension)


# -- the canonical sessions --------------------------------------------------------------------------
@pytest.mark.parametrize("extension", [False, True])
def test_canonical_session_passes(extension):
    fake, _, _ = canonical(extension)
    result = order(fake, extension)
    assert not result.failed and not result.not_judged, (result.violations, result.missing)
    assert list(result.steps) == list(E4_STEPS if extension else S1_STEPS)
    assert all(t is not None for t in result.steps.values())


def test_roles_and_steps():
    fake, cmd, stream = canonical()
    view = build_view(fake.session, DEFAULT_PROFILE)
    assert view.cmd is cmd and view.streams == [stream] and view.cut is None
    steps = observe_steps(view)
    assert steps["first pose"] == pytest.approx(0.02)
    assert steps["pose during the cycle"] == pytest.approx(0.22)
    assert steps["stream close"] == 0.9 and steps["command disconnect"] == 2.0


def test_cycle_on_before_the_stream_connects():
    fake, _, _ = canonical(cycle_on=0.005, poses=(0.02, 0.88))
    result = order(fake)
    assert any(v.startswith("CycleOn at +5.0 ms came") and "before stream connect" in v for v in result.violations)


def test_s1_judges_milestones_only_cycle_on_before_the_first_pose_is_fine():
    fake, _, _ = canonical(cycle_on=0.015, poses=(0.02, 0.88))  # stream connected at 10 ms, first pose at 20 ms
    assert not order(fake).failed


def test_stream_closed_after_the_command_connection():
    fake, _, _ = canonical(stream_close=2.1, cmd_close=2.0)
    result = order(fake)
    assert result.failed
    assert "command disconnect at +2000.0 ms came 100.00 ms before stream close" in result.violations[0]


def test_stream_left_open():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    fake.send(stream, 0.02, POSE)
    fake.send(cmd, 0.1, frame(Action.CYCLE_ON))
    fake.send(stream, 0.12, POSE)
    fake.send(cmd, 0.3, frame(Action.CYCLE_OFF))
    fake.close(cmd, 0.5)
    fake.close(stream, 5.5, BY_SUITE, "closed by the suite: left open 5 s")
    result = order(fake)
    assert any(m.startswith("stream close missing: the robot left it open") for m in result.missing)


def test_no_cycle_pose_is_noted_not_judged():
    fake, _, _ = canonical(poses=(0.02, 0.1))  # the stream stops before CycleOn: T2 judges the stream, S1 the milestones
    result = order(fake)
    assert not result.failed and any("no pose was streamed during the cycle" in n for n in result.notes)


def test_extension_actions_in_an_s1_session_hint_at_the_flag():
    fake, _, _ = canonical(extension=True)
    result = order(fake, extension=False)
    assert any("PROG_IDX" in v and "--extension" in v for v in result.violations)


def test_a_command_sent_twice():
    fake, cmd, _ = canonical()
    fake.send(cmd, 0.85, frame(Action.CYCLE_OFF))
    result = order(fake)
    assert any("CYCLE_OFF sent again" in v for v in result.violations)


def test_ping_and_registrations_are_allowed_anywhere():
    fake, cmd, _ = canonical()
    fake.send(cmd, 0.05, frame(Action.NONE))
    fake.send(cmd, 0.06, encode(request(Action.REGISTER_POSE, pose_blocks([(1.0,) * 6]))))
    assert not order(fake).failed


def test_poses_on_the_command_connection_are_the_source_s_own_calls():
    """ISIGHT(3,35) sends the current TP pose and ISIGHT(3,36) a register pose on the command connection."""
    fake, cmd, _ = canonical()
    fake.send(cmd, 0.0005, frame(Action.NONE))  # a ping before anything
    fake.send(cmd, 0.5, POSE)
    fake.send(cmd, 0.51, encode(request(Action.REGISTER_POSE, pose_blocks([(1.0,) * 6]))))
    fake.send(cmd, 0.52, encode(request(Action.TOLERANCE, tolerance_blocks([0.5, 1.0, 1.5]))))
    result = order(fake)
    assert not result.failed, result.violations


def test_busy_result_may_be_polled():
    fake = Fake()
    cmd = fake.conn(0.0)
    fake.send(cmd, 0.005, frame(Action.PROG_IDX, 1), value=1)
    stream = fake.conn(0.01)
    for i in range(40):
        fake.send(stream, 0.02 + i * 0.02, POSE)
    fake.send(cmd, 0.1, frame(Action.CYCLE_ON))
    fake.send(cmd, 0.5, frame(Action.CYCLE_OFF))
    fake.close(stream, 0.9)
    fake.send(cmd, 1.9, frame(Action.VISION_RESULT), value=202)
    fake.send(cmd, 2.0, frame(Action.VISION_RESULT), value=202)
    fake.send(cmd, 2.1, frame(Action.VISION_RESULT), value=1)
    fake.close(cmd, 2.2)
    result = order(fake, extension=True)
    assert not result.failed, result.violations


# -- the cut --------------------------------------------------------------------------------------------
def test_not_ready_cuts_the_session():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    fake.send(stream, 0.02, POSE)
    fake.send(cmd, 0.05, frame(Action.CYCLE_ON), error_code=ErrorCode.NOT_READY)
    fake.close(cmd, 0.06)
    fake.close(stream, 0.07)
    view = build_view(fake.session, DEFAULT_PROFILE)
    assert view.cut is not None and "0x0001" in view.cut.why
    result = judge_order(view, False)
    assert not result.failed
    assert result.not_judged == ["CycleOff", "stream close", "command disconnect"]


def test_the_box_closing_is_a_cut():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    fake.send(stream, 0.02, POSE)
    fake.send(cmd, 0.05, frame(Action.CYCLE_ON))
    fake.close(cmd, 0.0502, BY_BOX, "inject close-mid-cycle")
    fake.close(stream, 0.5)
    result = order(fake)
    assert not result.failed and "CycleOff" in result.not_judged


def test_a_step_skipped_before_the_cut_still_fails():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    fake.send(stream, 0.02, POSE)
    fake.send(cmd, 0.05, frame(Action.CYCLE_OFF))  # no CycleOn
    fake.send(cmd, 0.06, b"\x00garbage", request_like=False)  # the box stays silent: the cut
    result = order(fake)
    assert any(m.startswith("CycleOn missing") and "skipped" in m for m in result.missing)


def test_a_silent_first_connection_is_the_command_connection():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    fake.send(stream, 0.02, POSE, error_code=ErrorCode.POSE_ERROR)
    fake.close(cmd, 0.03)
    fake.close(stream, 0.031)
    view = build_view(fake.session, DEFAULT_PROFILE)
    assert view.cmd is cmd and not view.silent
    result = judge_order(view, False)
    assert not result.failed and result.not_judged


def test_no_request_at_all():
    fake = Fake()
    conn = fake.conn(0.0)
    fake.send(conn, 0.01, b"hello", request_like=False)
    fake.close(conn, 0.02)
    result = order(fake)
    assert result.failed and "no request" in result.violations[0]


def test_two_stream_connections():
    fake, _, _ = canonical()
    extra = fake.conn(0.3)
    fake.send(extra, 0.31, POSE)
    fake.close(extra, 0.4)
    result = order(fake)
    assert any(v.startswith("2 stream connections") for v in result.violations)


# -- A1/T1: awaited answers ----------------------------------------------------------------------------------
def test_answers_awaited_in_a_canonical_session():
    fake, _, _ = canonical(True)
    checked, bad = awaited(build_view(fake.session, DEFAULT_PROFILE), DEFAULT_PROFILE)
    assert checked == 3 and not bad


def test_a_request_before_the_previous_answer():
    fake = Fake()
    cmd = fake.conn(0.0)
    fake.send(cmd, 0.1, frame(Action.CYCLE_ON), answered=0.3)
    fake.send(cmd, 0.2, frame(Action.CYCLE_OFF))
    fake.close(cmd, 1.0)
    checked, bad = awaited(build_view(fake.session, DEFAULT_PROFILE), DEFAULT_PROFILE)
    assert checked == 1 and len(bad) == 1
    assert "sent CYCLE_OFF at +200.0 ms, 100.0 ms after CYCLE_ON" in bad[0] and "+300.0 ms" in bad[0]


def test_a_request_after_time_out_without_an_answer_is_fine():
    fake = Fake()
    cmd = fake.conn(0.0)
    fake.send(cmd, 0.1, frame(Action.CYCLE_ON), answered=None)
    fake.send(cmd, 5.1, frame(Action.CYCLE_OFF))
    fake.close(cmd, 6.0)
    assert awaited(build_view(fake.session, DEFAULT_PROFILE), DEFAULT_PROFILE) == (1, [])


def test_vision_result_is_bounded_by_vision_time_out():
    profile = DEFAULT_PROFILE.replace(vision_time_out_ms=10000)
    fake = Fake()
    cmd = fake.conn(0.0)
    fake.send(cmd, 0.1, frame(Action.VISION_RESULT), answered=None)
    fake.send(cmd, 6.0, frame(Action.NONE))
    fake.close(cmd, 20.0)
    checked, bad = awaited(build_view(fake.session, profile), profile)
    assert len(bad) == 1 and "10000 ms" in bad[0]


def test_closing_before_the_answer_and_the_time_out():
    fake = Fake()
    cmd = fake.conn(0.0)
    fake.send(cmd, 0.1, frame(Action.CYCLE_OFF), answered=None)
    fake.close(cmd, 0.5)
    checked, bad = awaited(build_view(fake.session, DEFAULT_PROFILE), DEFAULT_PROFILE)
    assert checked == 0 and len(bad) == 1 and "closed the connection" in bad[0]


def test_the_stream_may_pipeline():
    fake = Fake()
    cmd, stream = fake.conn(0.0), fake.conn(0.01)
    for _ in range(5):
        fake.send(stream, 0.02, POSE, answered=0.5)  # five poses at once, answers later
    fake.close(stream, 0.6)
    fake.close(cmd, 0.7)
    assert awaited(build_view(fake.session, DEFAULT_PROFILE), DEFAULT_PROFILE)[1] == []


# -- several cycles in one session (several parts primed) ---------------------------------------------
def test_several_cycles_in_one_session_are_canonical():
    """CycleOn -> CycleOff -> CycleOn -> CycleOff between stream on and stream off (issue 17's false alarm)."""
    fake, cmd, _ = canonical(cycle_on=0.2, cycle_off=0.4)
    fake.send(cmd, 0.5, frame(Action.CYCLE_ON))
    fake.send(cmd, 0.7, frame(Action.CYCLE_OFF))
    result = order(fake)
    assert not result.failed, (result.violations, result.missing)
    assert result.steps["CycleOn"] == pytest.approx(0.2) and result.steps["CycleOff"] == pytest.approx(0.7)


def test_cycle_on_twice_without_cycle_off_is_out_of_order():
    fake, cmd, _ = canonical(cycle_on=0.2, cycle_off=0.6)
    fake.send(cmd, 0.3, frame(Action.CYCLE_ON))
    result = order(fake)
    assert any(v.startswith("CYCLE_ON sent again at +300.0 ms while the cycle") for v in result.violations)


def test_a_second_cycle_after_the_stream_closed_is_out_of_order():
    fake, cmd, _ = canonical(cycle_on=0.2, cycle_off=0.4, stream_close=0.9, cmd_close=2.0)
    fake.send(cmd, 1.0, frame(Action.CYCLE_ON))
    fake.send(cmd, 1.1, frame(Action.CYCLE_OFF))
    result = order(fake)
    assert any("came" in v and "before CycleOff" in v for v in result.violations), result.violations


def test_a_second_cycle_left_on_is_a_violation():
    fake, cmd, _ = canonical(cycle_on=0.2, cycle_off=0.4)
    fake.send(cmd, 0.5, frame(Action.CYCLE_ON))
    result = order(fake)
    assert any("CycleOn at +500.0 ms is never closed" in v for v in result.violations), result.violations
