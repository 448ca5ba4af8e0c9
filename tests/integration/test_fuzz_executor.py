"""The fuzz executor (conformance/fuzz/executor.py): probes, connection reuse, isolation, liveness, UDP."""

from __future__ import annotations

import pytest

from conformance.endpoints.behaviour import BoxConfig
from conformance.fuzz.executor import Executor, alive
from conformance.fuzz.strategies import Strategies
from conformance.harness.client import Answer, Closed, Silence
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.model.verdicts import Verdict
from conformance.protocol import Action, Profile, Transport, answer, encode, encode_udp, pose_blocks, request
from tests.boxes import ScriptedBox, answering, silent
from tests.integration.test_fuzz_campaign import patched_box, zero_to_bad_pose_index

pytestmark = pytest.mark.timeout(60)
P = Profile()
S = Strategies(P, extension=True, udp=True)
POSE = encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])))
BAD_INDEX = encode(request(Action.POSE, pose_blocks([(0.0,) * 6], first_index=1)))


def executor(port: int, udp: int | None = None, **kw: object) -> Executor:
    return Executor(Target("127.0.0.1", port), P, Transcript("T"), udp_target=Target("127.0.0.1", udp) if udp else None,
                    **kw)  # type: ignore[arg-type]


def test_cases_against_the_bundled_box_pass_and_reuse_one_connection() -> None:
    with patched_box() as box:
        ex = executor(box.tcp_port, box.udp_port, liveness_every=4)
        results = [ex.run(S.case("t", "", data, "t")) for data in (POSE, BAD_INDEX, b"garbage", POSE)]
        ex.close()
    assert [r.verdict for r in results] == [Verdict.PASS] * 4
    assert len({r.conn for r in results}) == 1 and results[0].fresh and not results[1].fresh
    assert isinstance(results[0].outcomes[0], Answer) and results[1].outcomes[0].frame.error_code == 0x1001
    assert results[2].outcomes == [] and results[2].probe is Action.NONE  # silence, bounded by the probe
    assert results[3].liveness is not None and alive(results[3].liveness)  # every 4th case
    assert ex.stats.liveness_checks == 1 and ex.stats.connections == 1


def test_isolation_opens_a_connection_per_case_and_truncation_ends_the_stream() -> None:
    with patched_box() as box:
        ex = executor(box.tcp_port)
        ex.isolate = ex.settle = True
        a, b = ex.run(S.case("t", "", POSE, "t")), ex.run(S.case("t", "", POSE, "t"))
        cut = ex.run(S.case("t", "F5", POSE[:20], "t", eof=True))
        ex.close()
    assert a.conn != b.conn and a.verdict is b.verdict is Verdict.PASS
    assert cut.verdict is Verdict.PASS and isinstance(cut.end, Closed) and cut.liveness is None  # a normal end


def test_a_planted_defect_fails_and_a_box_closing_on_garbage_is_allowed() -> None:
    with patched_box(zero_to_bad_pose_index) as box:
        ex = executor(box.tcp_port)
        bad = ex.run(S.case("t", "B3", BAD_INDEX, "t"))
        ex.close()
    assert bad.verdict is Verdict.FAIL and bad.anomaly and bad.liveness is not None
    assert bad.judgement.failures[0].clause == "B3"
    with patched_box(config=BoxConfig(on_garbage="close")) as box:
        ex = executor(box.tcp_port)
        garbage = ex.run(S.case("t", "F1", b"garbage", "t"))
        after = ex.run(S.case("t", "", POSE, "t"))
        ex.close()
    assert garbage.verdict is Verdict.PASS and isinstance(garbage.end, Closed)
    assert after.verdict is Verdict.PASS and after.fresh and after.conn != garbage.conn


def test_a_silent_box_fails_within_the_time_out() -> None:
    with ScriptedBox(silent) as box:
        ex = executor(box.port, time_out_s=0.3)
        result = ex.run(S.case("t", "", POSE, "t"))
        ex.close()
    assert result.verdict is Verdict.FAIL and isinstance(result.end, Silence)
    # one finding: the box stopped answering at the first request (T1), not one per request it never reached
    assert {f.clause for f in result.judgement.failures} == {"T1"}
    assert result.liveness is not None and not alive(result.liveness)


def test_a_box_answering_twice_is_caught_even_when_the_extra_answer_looks_like_the_probe_s() -> None:
    with ScriptedBox(answering(lambda f: encode(answer(f.action)) * 2)) as box:
        ex = executor(box.port, time_out_s=1.0)
        result = ex.run(S.case("t", "", POSE, "t"))
        ex.close()
    assert result.verdict is Verdict.FAIL
    assert {f.clause for f in result.judgement.failures} == {"A1"}
    assert isinstance(result.end, Answer) and result.end.frame.action is Action.NONE


def test_udp_cases_go_to_the_udp_target() -> None:
    with patched_box() as box:
        ex = executor(box.tcp_port, box.udp_port)
        good = ex.run(S.case("t", "", encode_udp(request(Action.NONE)), "t", Transport.UDP))
        bad = ex.run(S.case("t", "F7", encode_udp(request(Action.NONE))[:-1] + b"\x00", "t", Transport.UDP))
        ex.close()
    assert good.verdict is bad.verdict is Verdict.PASS
    assert isinstance(good.outcomes[0], Answer) and bad.outcomes == []  # R7: dropped silently
    assert ex.stats.udp == 2


def test_a_probe_answered_with_an_error_ends_the_wait_at_once() -> None:
    """No time_out wait when the box answers the probe with an error (S3 broken for the POSE probe)."""
    with ScriptedBox(answering(lambda f: encode(answer(f.action, 0x1001 if f.action == Action.POSE else 0)))) as box:
        ex = executor(box.port, time_out_s=5.0)
        result = ex.run(S.case("t", "", encode(request(Action.NONE)), "t"))
        ex.close()
    assert result.probe is Action.POSE and isinstance(result.end, Answer) and result.end.frame.error_code == 0x1001
    assert [f.key for f in result.judgement.failures] == ["probe/code"]  # judged, not waited out as a hang


SPLICED_NONE = b"\xfe" + encode(request(Action.NONE))  # FE FE FE 00 01 ...: a NONE one byte in (R6 resync)


def test_the_probe_never_has_the_action_of_a_frame_embedded_in_the_bytes() -> None:
    ex = executor(1)  # never connects: probe_for only reads the bytes
    assert ex.probe_for(S.case("t", "F2", SPLICED_NONE, "t")) is not Action.NONE
    both = SPLICED_NONE + b"\xfe" + POSE
    assert ex.probe_for(S.case("t", "F2", both, "t")) not in (Action.NONE, Action.POSE)


def test_a_box_answering_the_embedded_frame_leaves_nothing_for_the_next_case() -> None:
    """A fine-resync box answers the NONE inside FE FE FE ...; with a NONE probe the probe's own answer came
    late, read as an extra answer in the next case (a false A1 "exactly one answer" on a reused connection)."""
    from tests.impls.box import start_box

    with start_box("resync-fine") as box:
        ex = executor(box.port)
        first = ex.run(S.case("t", "F2", SPLICED_NONE, "t"))
        second = ex.run(S.case("t", "B3", BAD_INDEX, "t"))
        ex.close()
    assert first.verdict is Verdict.PASS and first.probe is not Action.NONE
    assert [o.frame.action for o in first.outcomes] == [Action.NONE]  # the embedded frame's answer
    assert second.verdict is Verdict.PASS and second.conn == first.conn  # reused, nothing left over
    assert [o.frame.error_code for o in second.outcomes] == [0x1001]


def test_bytes_holding_every_probe_action_go_without_a_probe_and_are_judged_after_time_out() -> None:
    """Before, the fuzzer fell back to a NONE probe although the bytes held a NONE request: the first NONE
    answer (the embedded request's) ended the wait and the probe's own answer was left for the next case."""
    from conformance.harness.exchange import PROBE_ACTIONS, probe_request

    every = b"".join(encode(probe_request(a, P)) for a in PROBE_ACTIONS)
    with patched_box() as box:
        ex = executor(box.tcp_port, time_out_s=0.3)
        result = ex.run(S.case("t", "", every, "t"))
        ex.close()
    assert result.probe is None and result.verdict is Verdict.PASS, result.judgement.describe()
    assert [o.frame.action for o in result.outcomes if isinstance(o, Answer)] == list(PROBE_ACTIONS)
    assert isinstance(result.end, Silence)  # the wait ended at time_out, nothing left for a next case


def test_a_refusal_with_the_probe_s_action_then_a_close_is_a_legal_close() -> None:
    """Issue 17, knobs not_request=error refusal_action=00 framing_version=resume+12 framing_garbage=close: the
    box refuses a bad-version header with action 00 and an error, then closes on the bytes after it. With a NONE
    probe the refusal looked like the probe's (wrong) answer and the close went unseen: a false R6 NON-STRICT."""
    from tests.impls.boxcore import ThreadBox
    from tests.impls.policy import knob_choices

    knobs = {"not_request": "error", "refusal_action": "00", "framing_version": "resume+12", "framing_garbage": "close"}
    bad_version = bytes.fromhex("fefe0101260301000500841012c6300c0000")
    with ThreadBox(knob_choices(knobs)).start() as box:
        ex = executor(box.port)
        result = ex.run(S.case("t", "F2", bad_version, "t"))
        ex.close()
    assert result.probe is Action.NONE and isinstance(result.end, Closed)
    assert len(result.outcomes) == 1 and result.outcomes[0].raw[5] == Action.NONE  # the refusal, action 00
    assert result.verdict is Verdict.PASS, result.judgement.describe()


def test_a_refusal_with_the_probe_s_action_before_other_answers_stays_the_case_s() -> None:
    """Issue 17, knobs not_request=error refusal_action=00 (version resync one byte on) cycle_on_ready=first-not-ready:
    FE FE FE 00 01 01 ... is refused with NONE 0001, then the CycleOn one byte in is answered 0001, then the NONE probe
    0000. The refusal was taken for the probe's answer and the probe's 0000 for an extra one: a false A1/A4 FAIL."""
    from tests.impls.boxcore import ThreadBox
    from tests.impls.policy import knob_choices

    knobs = {"not_request": "error", "refusal_action": "00", "refusal_code": "0001", "cycle_on_ready": "first-not-ready"}
    spliced_cycle_on = b"\xfe" + encode(request(Action.CYCLE_ON))
    with ThreadBox(knob_choices(knobs)).start() as box:
        ex = executor(box.port)
        result = ex.run(S.case("t", "F2", spliced_cycle_on, "t"))
        ex.close()
    assert result.probe is Action.NONE and isinstance(result.end, Answer) and result.end.frame.error_code == 0
    assert [o.raw[5] for o in result.outcomes] == [Action.NONE, Action.CYCLE_ON]
    assert result.verdict is Verdict.PASS, result.judgement.describe()
