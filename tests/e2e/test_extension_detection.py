"""Extension E detection rests on positive evidence (issue 17): a refusal of 26/27 in any
way A5 allows is "not implemented"; a type-03 block, or 27 answered 0000, is "implemented".

Detection in-process against tiny loopback boxes (tests/boxes.py), well under a second each;
then the suite's E-dependent cases in a subprocess against the reference box refusing 26/27
each legal way (about 3 s each).
"""

from __future__ import annotations

import socket
from collections.abc import Callable
from pathlib import Path

import pytest

from conformance.endpoints.behaviour import BoxBehaviour, BoxConfig, Decision, Reaction
from conformance.harness.client import TcpConnection
from conformance.harness.extension_probe import detect_extension
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.protocol import (
    Action,
    Frame,
    Header,
    Profile,
    ProtocolError,
    StreamDecoder,
    TransferType,
    Transport,
    answer,
    encode,
    encode_raw,
    value_blocks,
)
from tests.boxes import ScriptedBox, answering, silent
from tests.e2e.test_cases_extension_udp import Patch, failing, reference_box, run_suite, verdicts

PROFILE = Profile(time_out_ms=2000)
E = (Action.PROG_IDX, Action.VISION_RESULT)


def refusal(action: int, error: int = 0x0003) -> bytes:
    """An A5 refusal: transfer type 10, ``action``, a non-zero error, no block (the issue's bytes)."""
    return encode_raw(Header(transfer_type=0x10, action=action, error_code=error))


def rest(frame: Frame) -> bytes:
    return encode(answer(frame.action))


def box(on_e: Callable[[Frame], bytes | None]) -> ScriptedBox:
    """A box answering 00-25 0000 and 26/27 with ``on_e(frame)`` (None: silence)."""
    return ScriptedBox(answering(lambda f: on_e(f) if f.action in E else rest(f)))


def closes_on_e(conn: socket.socket) -> None:
    """A box that closes the connection when it sees 26 or 27 (the third refusal A5 allows)."""
    decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
    conn.settimeout(10)
    while data := conn.recv(65536):
        for event in decoder.feed(data):
            if isinstance(event, Frame):
                if event.action in E:
                    conn.close()
                    return
                conn.sendall(rest(event))


def detect(target: str) -> tuple[bool, str, Transcript]:
    transcript = Transcript(case_id="detect")
    host, port = target.split(":")
    conn = TcpConnection(transcript, Target(host, int(port)), PROFILE, "extension detection").connect()
    try:
        found, how = detect_extension(conn)
    finally:
        conn.close()
    return found, how, transcript


REFUSALS: dict[str, Callable[[Frame], bytes | None]] = {
    "error-echoed-action": lambda f: refusal(f.action),
    "error-action-00": lambda f: refusal(0x00, 0x0001),
    "silence": lambda f: None,
}


@pytest.mark.parametrize("kind", list(REFUSALS))
def test_a_refusal_is_not_support(kind: str) -> None:
    with box(REFUSALS[kind]) as b:
        found, how, transcript = detect(b.target)
    assert found is False, how
    assert how.startswith("not implemented"), how
    # both actions were asked: a refusal of 27 alone does not settle it
    assert "result request (27):" in how and "ProgIdx (26):" in how, how
    if kind == "silence":
        assert how.count("no answer (the NONE probe behind it was answered)") == 2, how
        assert transcript.timeouts == 0  # silence to an unknown action is a legal refusal, not a late answer
    elif kind == "error-echoed-action":
        assert "action 27, error 0x0003, no block" in how and "action 26, error 0x0003, no block" in how, how
    else:
        assert how.count("action 00, error 0x0001, no block") == 2, how


def test_a_close_is_not_support() -> None:
    with ScriptedBox(closes_on_e) as b:
        found, how, _ = detect(b.target)
    assert found is False, how
    assert how.count("the box closed the connection") + how.count("the box reset the connection") == 2, how


def test_a_result_block_is_support() -> None:
    with box(lambda f: encode(answer(f.action, 0, value_blocks([1])))) as b:
        found, how, transcript = detect(b.target)
    assert found is True and how.startswith("implemented (detected: 27: its answer carries a type-03 block"), how
    assert "ProgIdx (26)" not in how  # 27 settled it: no ProgIdx was sent
    assert len([c for c in transcript.connections.values() if c.transport == "tcp"]) == 1


@pytest.mark.parametrize("name,on_e,why", [
    # E3 wrong: no block, but 27 answered 0000 with its action echoed
    ("27-0000-no-block", lambda f: encode(answer(f.action)), "27: it is answered 0000"),
    # E3 wrong: a ResultCode the box may not send (the answer does not parse), still a type-03 block
    ("27-result-404", lambda f: encode(answer(f.action, 0, value_blocks([404]))), "27: its answer carries a type-03"),
    # 27 refused with an error, 26 implemented: the box implements E (and E3 judges 27)
    ("26-only", lambda f: encode(answer(f.action, 0, value_blocks([7]))) if f.action == Action.PROG_IDX
     else refusal(f.action), "26: its answer carries a type-03 block"),
])
def test_a_wrong_implementation_is_support(name: str, on_e: Callable[[Frame], bytes], why: str) -> None:
    with box(on_e) as b:
        found, how, _ = detect(b.target)
    assert found is True, how
    assert why in how, how


def test_26_answered_0000_without_block_is_not_evidence() -> None:
    """Only 27 answered 0000 counts; a 26 answered 0000 without a block, 27 refused, is an A5 matter."""
    on_e: Callable[[Frame], bytes] = lambda f: encode(answer(f.action)) if f.action == Action.PROG_IDX \
        else refusal(f.action)  # noqa: E731
    with box(on_e) as b:
        found, how, _ = detect(b.target)
    assert found is False, how
    assert "action 26, error 0x0000, no block" in how, how


# -- the suite end to end: refusals come out clean, wrong implementations FAIL E ---------------

#: the cases that depend on the detection (the E cases, A5-02, F4-01's E part, the E sequences,
#: the extension vectors)
E_CASES = ["E*", "A5-02*", "F4-*", "SEQ-E4*", "A1-10*"]


def refusing(make: Callable[[int], Frame], actions: tuple[Action, ...] = E) -> Patch:
    """Patch the reference box to refuse ``actions`` with the error answer ``make(action)``."""

    def patch(b: BoxBehaviour) -> None:
        original = b.decide

        def decide(event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
            if isinstance(event, Frame) and event.action in actions:
                frame = make(event.action)
                return Decision(Reaction.NOT_UNDERSTOOD, frame, b.codec.encode(frame, Transport.TCP),
                                b.codec.encode(frame, Transport.UDP), "refusal: error")
            return original(event, transport)

        b.decide = decide  # type: ignore[method-assign]
        b.fast_path = False

    return patch


SUITE_REFUSALS: dict[str, tuple[BoxConfig, Patch | None]] = {
    "error-echoed-action": (BoxConfig(extension=False), refusing(lambda a: answer(Action(a), 0x0003))),
    "error-action-00": (BoxConfig(extension=False), refusing(lambda a: answer(Action.NONE, 0x0001))),
    "silence": (BoxConfig(extension=False), None),  # the reference box's own refusal
    "close": (BoxConfig(extension=False, on_garbage="close"), None),
}


@pytest.mark.parametrize("kind", list(SUITE_REFUSALS))
def test_a_box_refusing_26_27_comes_out_clean(kind: str, tmp_path: Path) -> None:
    """About 3 s each: E SKIPs, A5-02 judges 26/27 as unknown actions and PASSes."""
    config, patch = SUITE_REFUSALS[kind]
    with reference_box(config, patch) as b:
        results = run_suite(tmp_path, E_CASES, b)
    v = verdicts(results)
    assert not failing(results), v
    assert v["A5-02[26-prog-idx]"] == v["A5-02[27-vision-result]"] == "PASS", v
    e_cases = [cid for cid in v if cid.startswith(("E", "SEQ-E4", "A1-10[extension"))]
    assert len(e_cases) >= 15 and {v[cid] for cid in e_cases} == {"SKIP"}, v
    assert "not implemented (detected" in results["E3-01"]["message"]


def test_a_box_answering_26_but_refusing_27_fails_e3(tmp_path: Path) -> None:
    """27 refused with an error, 26 implemented: the box implements E (26's type-03 block), so the
    E cases judge its refusal of 27 (E3 FAILs) instead of SKIPping."""
    patch = refusing(lambda a: answer(Action(a), 0x0003), actions=(Action.VISION_RESULT,))
    with reference_box(BoxConfig(), patch) as b:
        results = run_suite(tmp_path, ["E*", "A5-02*"], b)
    v = verdicts(results)
    assert v["E3-01"] == "FAIL" and v["E2-01"] == "PASS", v
    assert v["A5-02[26-prog-idx]"] == v["A5-02[27-vision-result]"] == "SKIP", v


def test_a_box_silent_to_everything_is_asked_once() -> None:
    """Neither 27 nor the probe behind it answered: no evidence, and no second wait for 26."""
    with ScriptedBox(silent) as b:
        found, how, transcript = detect(b.target)
    assert found is False and "ProgIdx (26)" not in how and "result request (27): the box stayed silent" in how, how
    assert len([c for c in transcript.connections.values() if c.transport == "tcp"]) == 1


@pytest.mark.impls(seconds=30)
def test_the_whole_suite_against_a_box_refusing_26_27_with_an_error_is_clean(tmp_path: Path) -> None:
    """The issue-17 box end to end (about 25 s): 26/27 refused with the action echoed and error 0003,
    no block. Every case, FUZZ included: exit 0, no root cause, the report says what detection saw."""
    import json
    import subprocess
    import sys

    config, patch = SUITE_REFUSALS["error-echoed-action"]
    with reference_box(config, patch) as b:
        proc = subprocess.run([sys.executable, "-m", "conformance", "run", "--quiet", "--target",
                               f"127.0.0.1:{b.tcp_port}", "--udp-target", f"127.0.0.1:{b.udp_port}", "--report-dir",
                               str(tmp_path / "r"), "--pcap-dir", str(tmp_path / "p")],
                              capture_output=True, text=True, timeout=240, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    doc = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert doc["root_causes"] == [] and doc["totals"]["FAIL"] == doc["totals"]["NON-STRICT"] == 0, doc["totals"]
    assert doc["suite"]["extension"].startswith("not implemented (detected"), doc["suite"]["extension"]
    assert "action 27, error 0x0003, no block" in doc["suite"]["extension"]
    verdicts = {c["id"]: c["verdict"] for c in doc["cases"]}
    assert verdicts["A5-02[26-prog-idx]"] == verdicts["A5-02[27-vision-result]"] == "PASS"
    assert {v for cid, v in verdicts.items() if cid.startswith(("E1-", "E2-", "E3-", "E4-", "E5-"))} == {"SKIP"}
    html = (tmp_path / "r" / "report.html").read_text()
    assert "not implemented (detected" in html and "A5-02 judges 26/27 as unknown actions" in html
