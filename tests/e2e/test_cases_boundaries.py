"""Self-tests for the boundary cases (B3-03, B3-04, B4-03): each runs in a subprocess against a
small loopback box that parses frames its own way (2-6 s per run, seven runs;
the last checks F6-02 under --first-index 1)."""

from __future__ import annotations

import socket
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

from conformance.protocol import ACTION_ERROR, Action, answer, encode
from tests.boxes import ScriptedBox
from tests.e2e.test_cases_extension_udp import run_suite, verdicts

HEADER = 12
KNOWN = {int(a) for a in Action}
BOUNDARY_CASES = ["B3-03*", "B3-04*", "B4-03*"]
DATA = (Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE)
#: a block's index byte and its floats -> accepted?
Check = Callable[[list[int], list[float]], bool]


def strict_indexes(indexes: list[int], floats: list[float]) -> bool:
    return indexes == list(range(len(indexes)))


def parsing_box(accept: Check, on_refusal: str = "error") -> Callable[[socket.socket], None]:
    """A box answering NONE/CycleOn/CycleOff 0000, and a data request 0000 when ``accept(indexes, floats)``,
    else with the action's error (or by closing the connection: ``on_refusal="close"``, or by never
    answering on that connection again: ``"hang"``)."""

    def handler(conn: socket.socket) -> None:
        conn.settimeout(10)
        buf = b""
        while data := conn.recv(65536):
            buf += data
            while len(buf) >= HEADER:
                n, length = buf[7], int.from_bytes(buf[8:10], "big")
                size = HEADER + n * length + 2
                if len(buf) < size:
                    break
                action, body, buf = buf[5], buf[HEADER:size - 2], buf[size:]
                if action not in KNOWN:
                    continue
                ok = True
                if Action(action) in DATA:
                    blocks = [body[k * length:(k + 1) * length] for k in range(n)]
                    floats = [f for b in blocks for f in struct.unpack(f">{(length - 1) // 4}f", b[1:])]
                    ok = n > 0 and accept([b[0] for b in blocks], floats)
                if not ok and on_refusal == "close":
                    conn.close()
                    return
                if not ok and on_refusal == "hang":
                    while conn.recv(65536):
                        pass
                    return
                conn.sendall(encode(answer(Action(action), 0 if ok else ACTION_ERROR[Action(action)])))

    return handler


def run(tmp_path: Path, accept: Check, on_refusal: str = "error", *extra: str) -> dict[str, dict[str, Any]]:
    with ScriptedBox(parsing_box(accept, on_refusal)) as box:
        return run_suite(tmp_path, BOUNDARY_CASES, None, "--target", box.target, "--time-out", "1000", *extra)


def test_a_box_that_checks_indexes_passes(tmp_path: Path) -> None:
    results = run(tmp_path, strict_indexes)
    v = verdicts(results)
    assert len(v) == 9 and set(v.values()) == {"PASS"}, v


def test_a_box_indexing_from_1_passes_under_its_profile(tmp_path: Path) -> None:
    """With --first-index 1 the 255-block requests end at index 255, the wrong ones at 17/129 carry 01."""
    results = run(tmp_path, lambda indexes, floats: indexes == list(range(1, len(indexes) + 1)), "error",
                  "--first-index", "1")
    v = verdicts(results)
    assert len(v) == 9 and set(v.values()) == {"PASS"}, v


def test_an_index_counter_wrapping_at_16_fails_b3_at_block_17(tmp_path: Path) -> None:
    results = run(tmp_path, lambda indexes, floats: indexes == [k % 16 for k in range(len(indexes))])
    v = verdicts(results)
    for action in ("pose", "register-pose", "tolerance"):
        assert v[f"B3-03[{action}]"] == "FAIL" and v[f"B3-04[{action}]"] == "FAIL", v
        # valid requests refused from 17 blocks on; a wrong index accepted at block 17
        assert results[f"B3-03[{action}]"]["message"].startswith("17 blocks: "), results[f"B3-03[{action}]"]
        assert "31 blocks" in results[f"B3-03[{action}]"]["message"]
        assert "16 blocks" not in results[f"B3-03[{action}]"]["message"]
        assert results[f"B3-04[{action}]"]["message"].startswith("block 17 of 17: ")
        assert v[f"B4-03[{action}]"] == "PASS"


def no_zero_no_negative_tolerance(indexes: list[int], floats: list[float]) -> bool:
    """0.0 taken for "missing" anywhere, and a negative tolerance refused."""
    tolerances = len(floats) == len(indexes)  # one float per block
    return strict_indexes(indexes, floats) and 0.0 not in floats and not (tolerances and min(floats) < 0)


def test_zero_taken_for_missing_and_a_negative_tolerance_refused_fail_b4(tmp_path: Path) -> None:
    results = run(tmp_path, no_zero_no_negative_tolerance)
    v = verdicts(results)
    for action in ("pose", "register-pose", "tolerance"):
        message = results[f"B4-03[{action}]"]["message"]
        assert v[f"B4-03[{action}]"] == "FAIL" and message.startswith("zero: "), message
        also = message.split("also not passed: ")[1]
        assert "neg-zero" in also and "1e6" not in also.replace("neg-1e6", ""), message
        assert ("negative-tolerance" in also) is (action == "tolerance"), message


def test_a_box_closing_on_parse_errors_is_non_strict_and_every_position_is_judged(tmp_path: Path) -> None:
    results = run(tmp_path, strict_indexes, on_refusal="close")
    v = verdicts(results)
    for action in ("pose", "register-pose", "tolerance"):
        assert v[f"B3-04[{action}]"] == "NON-STRICT", v
        message = results[f"B3-04[{action}]"]["message"]
        # the box closed at each: a fresh connection for the next, all 22 judged (12 named, then "…")
        assert message.startswith("block 2 of 2: ") and "block 17 of 31" in message and "…)" in message, message
        assert v[f"B3-03[{action}]"] == v[f"B4-03[{action}]"] == "PASS", v


def test_a_box_hanging_after_a_parse_error_ends_the_case_at_once(tmp_path: Path) -> None:
    """Bounded time: one wait for the silent box, not one per request left."""
    results = run(tmp_path, strict_indexes, on_refusal="hang")
    for action in ("pose", "register-pose", "tolerance"):
        case = results[f"B3-04[{action}]"]
        assert case["verdict"] == "NON-STRICT", case
        assert case["message"].startswith("block 2 of 2: ") and "the box went silent; the 21 requests after it were " \
            "not sent" in case["message"], case["message"]
        assert results[f"B3-03[{action}]"]["verdict"] == "PASS"


def test_f6_02_indexes_its_pose_from_the_profiles_first_index(tmp_path: Path) -> None:
    """A box indexing from 1 that ignores the TCP check field accepts the CRC-carrying pose of F6-02
    (it was sent indexed from 0 whatever --first-index said: a NON-STRICT false alarm)."""
    with ScriptedBox(parsing_box(lambda indexes, floats: indexes == list(range(1, len(indexes) + 1)))) as box:
        results = run_suite(tmp_path, ["F6-02"], None, "--target", box.target, "--time-out", "1000", "--first-index", "1")
    assert verdicts(results) == {"F6-02": "PASS"}, results.get("F6-02")
