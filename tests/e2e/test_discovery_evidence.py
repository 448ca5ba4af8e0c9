"""PROFILE-01 infers a reading only from positive evidence (issue 17): a reading no answer singles
out is reported as not determined (the profile's kept, a guess), never as fitting the box.

Each test runs PROFILE-01 in a subprocess against a loopback box (about 2 s each).
"""

from __future__ import annotations

import socket
from pathlib import Path

from conformance.protocol import Action, answer, encode
from tests.boxes import ScriptedBox
from tests.e2e.test_cases_extension_udp import _udp_answers_bad_crc, reference_box, run_suite

HEADER = 12
KNOWN = {int(a) for a in Action}


def yes_box(conn: socket.socket) -> None:
    """Answers every frame-shaped input 0000 with its action, whatever its version, indexes or check:
    no answer of it tells one reading from another."""
    conn.settimeout(10)
    buf = b""
    while data := conn.recv(65536):
        buf += data
        while len(buf) >= HEADER:
            size = HEADER + buf[7] * int.from_bytes(buf[8:10], "big") + 2
            if len(buf) < size:
                break
            action, buf = buf[5], buf[size:]
            conn.sendall(encode(answer(Action(action) if action in KNOWN else Action.NONE)))


def test_a_box_answering_everything_determines_nothing(tmp_path: Path) -> None:
    with ScriptedBox(yes_box) as box:
        results = run_suite(tmp_path, ["PROFILE-*"], None, "--target", box.target, "--time-out", "1000")
    case = results["PROFILE-01"]
    assert case["verdict"] == "INFORMATIONAL", case
    message = case["message"]
    assert "header fields in either byte order" in message and "first block index 0 or 1" in message, message
    assert "not determined" in message and "header byte order, first block index, UDP CRC" in message, message
    assert "the profile in use fits" not in message, message
    if "details" in case:
        assert case["details"]["undetermined"] == ["header byte order", "first block index", "UDP CRC"]
        assert case["details"]["discovered"] == {}


def test_a_box_answering_any_udp_check_leaves_the_crc_undetermined(tmp_path: Path) -> None:
    with reference_box(patch=_udp_answers_bad_crc(0)) as box:
        results = run_suite(tmp_path, ["PROFILE-*"], box)
    message = results["PROFILE-01"]["message"]
    assert "UDP CRC: not determined: the box answers a NONE datagram 0000 whatever its check" in message, message
    assert "header fields big-endian; first block index 0" in message, message
    assert "not determined (no answer singled one reading out" in message and message.endswith(": UDP CRC"), message
    assert "the profile in use fits" not in message, message
