"""Legal refusals the passive judges must accept (issue 26, found by the robot ↔ monitor ↔ box pairs):

* a box without the extension E may stay silent on 26/27 (A5, legal row extension-refusal): with no
  answer to 26 or 27 on the connection, its silence is INCONCLUSIVE, not an A1 FAIL; once it has
  answered one, silence on the next is a FAIL again;
* after the box's malformed answer the robot may move on (or stop): its next request is not an A1
  violation of the robot's (the box's frame error is filed, on the box).
"""

from __future__ import annotations

from pathlib import Path

from conformance.analyze import AnalyzeConfig, analyze, build_cases
from conformance.model.verdicts import Verdict
from conformance.protocol import Action, answer, encode, request, value_blocks
from tests.analyze_util import Capture, exchange

LOOSE = AnalyzeConfig(rate_tolerance=0.5, jitter_tolerance=3.0)
PROG_IDX = encode(request(Action.PROG_IDX, value_blocks([7])))
RESULT = encode(request(Action.VISION_RESULT))


def _cases(cap: Capture, tmp_path: Path) -> dict:
    return {c.id: c for c in build_cases(analyze(cap.write(tmp_path / "s.pcapng"), LOOSE))}


def test_silence_on_progidx_from_a_box_that_may_lack_the_extension_is_inconclusive(tmp_path: Path) -> None:
    cap = Capture()
    cmd = cap.tcp(41000)
    cmd.robot(PROG_IDX)
    cmd.close()  # the robot gives up after its time_out
    c = _cases(cap, tmp_path)
    assert c["OBS-A1-box"].verdict is Verdict.INCONCLUSIVE, c["OBS-A1-box"].message
    assert "without the extension" in c["OBS-A1-box"].message


def test_silence_on_27_after_answering_26_is_still_a_fail(tmp_path: Path) -> None:
    cap = Capture()
    cmd = cap.tcp(41000)
    exchange(cmd, PROG_IDX, encode(answer(Action.PROG_IDX, blocks=value_blocks([200]))))
    cmd.robot(RESULT)
    cmd.robot(b"", t=cap.t + 6.0)  # time_out passes
    cmd.close()
    c = _cases(cap, tmp_path)
    assert c["OBS-A1-box"].verdict is Verdict.FAIL
    assert "VISION_RESULT never answered" in c["OBS-A1-box"].message


def test_the_robot_moving_on_after_a_malformed_answer_is_not_its_a1(tmp_path: Path) -> None:
    cap = Capture()
    cmd = cap.tcp(41000)
    bad = bytearray(encode(answer(Action.NONE)))
    bad[2:4] = bytes(reversed(bad[2:4]))  # the version in the other byte order (F2)
    cmd.robot(encode(request(Action.NONE)))
    cmd.box(bytes(bad))
    cmd.robot(encode(request(Action.CYCLE_ON)))  # the robot took the malformed answer as the answer
    cmd.box(bytes(bad[:5]) + bytes([Action.CYCLE_ON]) + bytes(bad[6:]))
    cmd.close()
    c = _cases(cap, tmp_path)
    assert c["OBS-F2-box"].verdict is Verdict.FAIL
    assert c["OBS-A1-robot"].verdict is not Verdict.FAIL, c["OBS-A1-robot"].message


def test_a_robot_that_gives_up_at_time_out_on_a_late_answer_is_not_blamed_for_s1(tmp_path: Path) -> None:
    from tests.analyze_util import POSE, POSE_OK

    cap = Capture()
    cmd, stream = cap.tcp(41000), cap.tcp(41001)
    for _ in range(20):
        stream.robot(POSE, t=cap.t + 0.02)
        stream.box(POSE_OK, t=cap.t + 0.0004)
    cmd.robot(encode(request(Action.CYCLE_ON)))
    for _ in range(10):
        stream.robot(POSE, t=cap.t + 0.02)
        stream.box(POSE_OK, t=cap.t + 0.0004)
    cmd.box(encode(answer(Action.CYCLE_ON)), t=cap.t + 6.0)  # after time_out (5 s): the robot gave up
    cmd.close()  # no CycleOff: the robot stops its session
    stream.close()
    c = _cases(cap, tmp_path)
    assert c["OBS-T1-box"].verdict is Verdict.FAIL
    assert c["OBS-S1-robot"].verdict is not Verdict.FAIL, c["OBS-S1-robot"].message


def test_a_box_echoing_a_little_endian_index_is_not_blamed_for_f4(tmp_path: Path) -> None:
    cap = Capture()
    cmd = cap.tcp(41000)
    swapped = encode(request(Action.PROG_IDX, value_blocks([7 << 24])))  # 7 written little-endian
    echoed = encode(answer(Action.PROG_IDX, blocks=value_blocks([7 << 24])))
    exchange(cmd, swapped, echoed)
    cmd.close()
    c = _cases(cap, tmp_path)
    assert c["OBS-F4-robot"].verdict is Verdict.FAIL
    assert c["OBS-F4-box"].verdict is not Verdict.FAIL, c["OBS-F4-box"].message


def test_four_poses_before_a_refusal_are_too_few_for_a_rate(tmp_path: Path) -> None:
    from tests.analyze_util import POSE, POSE_OK

    cap = Capture()
    cmd, stream = cap.tcp(41000), cap.tcp(41001)
    for gap in (0.02, 0.01, 0.012, 0.014):  # 62 Hz over three intervals, declared 50
        stream.robot(POSE, t=cap.t + gap)
        stream.box(POSE_OK, t=cap.t + 0.0004)
    exchange(cmd, encode(request(Action.CYCLE_ON)), encode(answer(Action.CYCLE_ON, error_code=1)))  # not ready
    stream.close()
    cmd.close()
    c = {c.id: c for c in build_cases(analyze(cap.write(tmp_path / "s.pcapng"), AnalyzeConfig()))}  # ±10 %
    assert c["OBS-T2-robot"].verdict is Verdict.INCONCLUSIVE, c["OBS-T2-robot"].message


def test_latency_growing_by_less_than_one_period_is_no_backlog_but_more_is() -> None:
    from conformance.analyze.capture_timing import backlog
    from conformance.analyze.findings import Series

    def grown(last_ms: float) -> bool:
        s = Series()
        for i in range(40):
            s.add(5.0 if i < 20 else last_ms)
        b = backlog(s, 20.0)  # 20 Hz: a period of 50 ms
        assert b is not None
        return b.grows

    assert not grown(47.0)  # the box is less than one pose behind (a loaded machine)
    assert grown(80.0)
