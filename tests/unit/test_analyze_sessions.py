"""Sessions across connections (conformance/analyze/sessions.py): grouping, S1/E4 with
certify-robot's judgement, A1 (the robot awaits answers), S5 (the robot closes), and the
cuts a capture makes (a mid-session start, a refusal, the capture's end)."""

from __future__ import annotations

from pathlib import Path

from conformance.analyze import AnalyzeConfig, analyze, build_cases
from conformance.analyze.sessions import ObservedView
from conformance.model.verdicts import Verdict
from conformance.observed.session import SessionView
from conformance.protocol import Action, answer, encode, request, value_blocks
from tests.analyze_util import POSE, POSE_OK, Capture, canonical, exchange

LOOSE = AnalyzeConfig(rate_tolerance=0.5, jitter_tolerance=3.0)


def judged(cap: Capture, tmp_path: Path, config: AnalyzeConfig = LOOSE) -> dict:
    a = analyze(cap.write(tmp_path / "s.pcapng"), config)
    return {c.id: c for c in build_cases(a)} | {"_stats": a.ctx.stats}


def test_two_sessions_one_after_the_other_are_each_judged(tmp_path):
    cap = Capture()
    canonical(cap, port=41000)
    canonical(cap, port=42000)
    c = judged(cap, tmp_path)
    assert c["_stats"].sessions == 2
    assert c["OBS-S1-robot"].verdict is Verdict.PASS and "2 sessions judged" in c["OBS-S1-robot"].message


def test_a_robot_that_does_not_await_answers_fails_a1(tmp_path):
    cap = Capture()
    cmd = cap.tcp(41000)
    stream = cap.tcp(41001)
    stream.robot(POSE)
    stream.box(POSE_OK)
    cmd.robot(encode(request(Action.CYCLE_ON)))
    cmd.robot(encode(request(Action.CYCLE_OFF)))  # before CycleOn's answer
    cmd.box(encode(answer(Action.CYCLE_ON)))
    cmd.box(encode(answer(Action.CYCLE_OFF)))
    stream.close()
    cmd.close()
    c = judged(cap, tmp_path)
    assert c["OBS-A1-robot"].verdict is Verdict.FAIL
    assert "before its answer" in c["OBS-A1-robot"].message and "frame" in c["OBS-A1-robot"].message


def test_a_connection_left_open_past_the_linger_fails_s5(tmp_path):
    cap = Capture()
    cmd = cap.tcp(41000)
    stream = cap.tcp(41001)
    stream.robot(POSE)
    stream.box(POSE_OK)
    exchange(cmd, encode(request(Action.CYCLE_ON)), encode(answer(Action.CYCLE_ON)))
    cmd.close()
    stream.robot(POSE, t=cap.t + 10.0)  # ten seconds after the command connection closed
    stream.box(POSE_OK)
    stream.close()
    c = judged(cap, tmp_path)
    assert c["OBS-S5-robot"].verdict is Verdict.FAIL and "left it open" in c["OBS-S5-robot"].message
    assert judged(cap, tmp_path, AnalyzeConfig(linger_s=30))["OBS-S5-robot"].verdict is Verdict.PASS


def test_a_session_with_prog_idx_is_judged_as_e4(tmp_path):
    cap = Capture()
    cmd = cap.tcp(41000)
    exchange(cmd, encode(request(Action.PROG_IDX, value_blocks([2]))),
             encode(answer(Action.PROG_IDX, blocks=value_blocks([2]))))
    cmd.close()
    c = judged(cap, tmp_path)
    assert c["OBS-E4-robot"].verdict is Verdict.FAIL  # no stream, no cycle: missing steps
    assert c["OBS-S1-robot"].verdict is Verdict.SKIP
    assert "stream connect missing" in c["OBS-E4-robot"].message
    forced = judged(cap, tmp_path, AnalyzeConfig(extension=False))
    assert forced["OBS-S1-robot"].verdict is Verdict.FAIL and "--extension" in forced["OBS-S1-robot"].message


def test_a_session_already_running_when_the_capture_starts_is_inconclusive(tmp_path):
    cap = Capture()
    cmd = cap.tcp(41000, handshake=False)
    exchange(cmd, encode(request(Action.CYCLE_OFF)), encode(answer(Action.CYCLE_OFF)))
    cmd.close()
    c = judged(cap, tmp_path)
    assert c["OBS-S1-robot"].verdict is Verdict.INCONCLUSIVE and "mid-session" in c["OBS-S1-robot"].message


def test_what_the_robot_did_not_do_after_the_box_refused_is_not_judged(tmp_path):
    cap = Capture()
    cmd = cap.tcp(41000)
    stream = cap.tcp(41001)
    stream.robot(POSE)
    stream.box(POSE_OK)
    exchange(cmd, encode(request(Action.CYCLE_ON)), encode(answer(Action.CYCLE_ON, 0x0001)))
    stream.close()
    cmd.close()
    c = judged(cap, tmp_path)
    assert c["OBS-S1-robot"].verdict is Verdict.INCONCLUSIVE and "0x0001" in c["OBS-S1-robot"].message


def test_the_view_names_frames():
    base = {f: None for f in SessionView.__dataclass_fields__}
    base.update(frames={}, exchanges={}, commands=[], streams=[], silent=[], t0=10.0)
    view = ObservedView(**base, frame_at={10.5: 42})
    assert view.ms(10.5) == "+500.0 ms (frame 42)" and view.ms(11.0) == "+1000.0 ms"
