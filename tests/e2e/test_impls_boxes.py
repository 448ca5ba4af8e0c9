"""The independent boxes (tests/impls) behave as designed: raw loopback sockets, hand-written bytes."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.impls import wire_format as wire
from tests.impls.box import VARIANTS, start_box
from tests.impls.boxcore import ThreadBox
from tests.impls.expectations import EXPECTATIONS
from tests.impls.framers import Close, Frame, Framer, Framing, Garbage, Rejected, ResyncFine, SkipHeader, TrustHeader
from tests.impls.policy import knob_choices

ROOT = Path(__file__).resolve().parents[2]
NONE = bytes.fromhex("fefe 0001 01 00 00 00 0000 0000 0000")
NONE_OK = bytes.fromhex("fefe 0001 10 00 00 00 0000 0000 0000")
CYCLE_ON = bytes.fromhex("fefe 0001 01 01 00 00 0000 0000 0000")
CYCLE_OFF = bytes.fromhex("fefe 0001 01 02 00 00 0000 0000 0000")
CONFORMING = [n for n, v in VARIANTS.items() if v.conforming]


def pose(index: int = 0, x: float = 1.0, length: int = 25) -> bytes:
    block = struct.pack(">B6f", index, x, 2.0, 3.0, 4.0, 5.0, 6.0)[:length].ljust(length, b"\0")
    return struct.pack(">HHBBBBHH", 0xFEFE, 1, 1, 0x23, 1, 1, length, 0) + block + b"\0\0"


def tolerance(value: float) -> bytes:
    return bytes.fromhex("fefe 0001 01 25 02 01 0005 0000") + struct.pack(">Bf", 0, value) + b"\0\0"


def answer(action: int, error: int = 0) -> bytes:
    return struct.pack(">HHBBBBHH", 0xFEFE, 1, 0x10, action, 0, 0, 0, error) + b"\0\0"


@contextlib.contextmanager
def box(name: str) -> Iterator[ThreadBox]:
    b = start_box(name)
    try:
        yield b
    finally:
        b.stop()


def connect(b: ThreadBox) -> socket.socket:
    s = socket.create_connection(("127.0.0.1", b.port), timeout=5)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def read(s: socket.socket, n: int, bound: float = 5.0) -> bytes:
    """Up to ``n`` bytes, waiting at most ``bound`` seconds (less on EOF)."""
    out = b""
    deadline = time.monotonic() + bound
    while len(out) < n and (left := deadline - time.monotonic()) > 0:
        s.settimeout(left)
        try:
            data = s.recv(n - len(out))
        except TimeoutError:
            break
        except ConnectionResetError:
            return out
        if not data:
            break
        out += data
    return out


def silent(s: socket.socket, wait: float = 0.5) -> bool:
    """No byte (and no close) within ``wait`` seconds."""
    s.settimeout(wait)
    try:
        s.recv(1)
    except TimeoutError:
        return True
    return False


def closed(s: socket.socket, bound: float = 5.0) -> bool:
    s.settimeout(bound)
    try:
        return s.recv(1) == b""
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False


# -- framers, sans-I/O -----------------------------------------------------------------------------------
def test_fine_framer_finds_a_frame_inside_a_rejected_header() -> None:
    f = ResyncFine()
    f.feed(bytes.fromhex("fefe0001") + NONE)
    events = list(f.events())
    assert isinstance(events[0], Rejected)
    frames = [e for e in events if isinstance(e, Frame)]
    assert [e.data for e in frames] == [NONE]


def test_skip_framer_loses_the_frame_inside_a_rejected_header() -> None:
    f = SkipHeader()
    f.feed(bytes.fromhex("fefe0001") + NONE)
    events = list(f.events())
    assert not [e for e in events if isinstance(e, Frame)]
    assert sum(e.size for e in events if isinstance(e, Garbage)) == len(NONE) + 4


def test_trust_framer_keeps_at_most_one_legal_frame() -> None:
    f = TrustHeader()
    f.feed(bytes.fromhex("fefe 0001 10 23 01 ff ffff 0000") + b"\x11" * 100_000)
    list(f.events())
    assert len(f.buf) <= wire.MAX_BODY + 14


# -- every conforming box ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", CONFORMING)
def test_conforming_boxes_answer_the_well_formed_requests(name: str) -> None:
    with box(name) as b, connect(b) as s:
        s.sendall(NONE + pose() + tolerance(0.5) + CYCLE_ON + CYCLE_OFF)
        assert read(s, 70) == NONE_OK + answer(0x23) + answer(0x25) + answer(0x01) + answer(0x02)


@pytest.mark.parametrize("name", CONFORMING)
def test_conforming_boxes_reject_malformed_poses_and_nan(name: str) -> None:
    with box(name) as b, connect(b) as s:
        s.sendall(pose(index=1))
        assert read(s, 14) == answer(0x23, 0x1001)
        s.sendall(pose(length=24))
        assert read(s, 14) == answer(0x23, 0x1001)
        s.sendall(tolerance(math.nan))
        assert read(s, 14) == answer(0x25, 0x1002)
        s.sendall(pose(x=math.inf))
        assert read(s, 14) == answer(0x23, 0x1001)


@pytest.mark.parametrize("name", [n for n in CONFORMING if VARIANTS[n].choices.has_extension])
def test_extension_boxes_answer_26_and_27_with_a_block(name: str) -> None:
    prog_idx = bytes.fromhex("fefe 0001 01 26 03 01 0005 0000 00 ffffffff 0000")
    with box(name) as b, connect(b) as s:
        s.sendall(prog_idx)
        assert read(s, 19) == bytes.fromhex("fefe 0001 10 26 03 01 0005 0000 00 ffffffff 0000")
        s.sendall(bytes.fromhex("fefe 0001 01 27 00 00 0000 0000 0000"))
        assert read(s, 19) == bytes.fromhex("fefe 0001 10 27 03 01 0005 0000 00 00000001 0000")
        two = bytes.fromhex("fefe 0001 01 26 03 02 0005 0000 00 00000007 01 00000008 0000")
        s.sendall(two + NONE)  # ProgIdx carries exactly one block (E2): never 0000
        got = read(s, 14 + 19, bound=1.0)
        assert got.endswith(NONE_OK) and bytes.fromhex("00000007") not in got


def test_nan_1001_box_has_no_extension() -> None:
    with box("nan-1001") as b, connect(b) as s:
        s.sendall(bytes.fromhex("fefe 0001 01 27 00 00 0000 0000 0000"))
        assert silent(s)


# -- the framing choices on the wire ---------------------------------------------------------------------------
def test_resync_fine_answers_the_none_inside_a_rejected_header() -> None:
    with box("resync-fine") as b, connect(b) as s:
        s.sendall(bytes.fromhex("fefe0001") + NONE)
        assert read(s, 14) == NONE_OK
        assert silent(s, 0.3)  # exactly one answer


@pytest.mark.parametrize("name", ["skip-header", "trust-header"])
def test_skip_and_trust_do_not_answer_it(name: str) -> None:
    with box(name) as b, connect(b) as s:
        s.sendall(bytes.fromhex("fefe0001") + NONE)
        assert silent(s)


def test_close_on_garbage_closes_but_answers_malformed_requests() -> None:
    with box("close-on-garbage") as b:
        with connect(b) as s:
            s.sendall(pose(length=24))
            assert read(s, 14) == answer(0x23, 0x1001)
            s.sendall(b"hello")
            assert closed(s)
        with connect(b) as s:
            s.sendall(bytes.fromhex("fefe 0001 01 03 00 00 0000 0000 0000"))  # unknown action 03
            assert closed(s)


def test_unknown_error_answers_not_requests_with_ffff() -> None:
    with box("unknown-error") as b, connect(b) as s:
        s.sendall(bytes.fromhex("fefe 0001 01 03 00 00 0000 0000 0000"))
        assert read(s, 14) == answer(0x03, 0xFFFF)


def test_strict_cycle_is_per_connection() -> None:
    with box("strict-cycle") as b, connect(b) as s, connect(b) as t:
        s.sendall(CYCLE_OFF)
        assert read(s, 14) == answer(0x02, 0x0002)
        s.sendall(CYCLE_ON + CYCLE_ON)
        assert read(s, 28) == answer(0x01) + answer(0x01, 0x0001)
        t.sendall(CYCLE_ON)
        assert read(t, 14) == answer(0x01)
        t.sendall(bytes.fromhex("fefe 0001 01 00 00 00 0000 0001 0000"))  # a request with an error field
        assert read(t, 14) == answer(0x00, 0xFFFF)  # a malformed 00: malformed_blockless=error


def test_strict_cycle_box_shares_the_cycle() -> None:
    with box("strict-cycle-box") as b, connect(b) as s, connect(b) as t:
        s.sendall(CYCLE_ON)
        assert read(s, 14) == answer(0x01)
        t.sendall(CYCLE_ON)
        assert read(t, 14) == answer(0x01, 0x0001)


def test_skip_header_checks_the_tcp_check_field() -> None:
    with box("skip-header") as b, connect(b) as s:
        s.sendall(CYCLE_OFF[:-2] + b"\xbe\xef")
        assert read(s, 14) == answer(0x02, 0x0002)
        crc = wire.crc16_modbus(CYCLE_OFF[:-2]).to_bytes(2, "big")
        s.sendall(CYCLE_OFF[:-2] + crc)
        assert read(s, 14) == answer(0x02)


def test_byte_by_byte_writes_one_byte_per_send() -> None:
    class Conn:
        def __init__(self) -> None:
            self.sends: list[bytes] = []

        def send(self, data: memoryview) -> int:
            self.sends.append(bytes(data))
            return len(data)

    b = ThreadBox(VARIANTS["byte-by-byte"].choices)
    try:
        conn = Conn()
        assert b._write(conn, NONE_OK)  # type: ignore[arg-type]
        assert conn.sends == [bytes([x]) for x in NONE_OK]
    finally:
        b.stop()


def test_trust_header_serves_udp_and_drops_bad_datagrams() -> None:
    with box("trust-header") as b, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as u:
        assert b.udp_port is not None
        u.settimeout(5)
        frame = NONE[:-2] + wire.crc16_modbus(NONE[:-2]).to_bytes(2, "big")
        u.sendto(NONE, ("127.0.0.1", b.udp_port))  # a zero check over UDP: dropped (R7)
        u.sendto(frame, ("127.0.0.1", b.udp_port))
        data = u.recv(100)
        assert data == NONE_OK[:-2] + wire.crc16_modbus(NONE_OK[:-2]).to_bytes(2, "big")
        u.settimeout(0.3)
        with pytest.raises(TimeoutError):
            u.recv(100)


# -- the broken boxes: one defect each ----------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "request_", "expected"), [
    ("swapped-version", NONE, bytes.fromhex("fefe 0100 10 00 00 00 0000 0000 0000")),
    ("swapped-error", pose(index=1), bytes.fromhex("fefe 0001 10 23 00 00 0000 0110 0000")),
    ("swapped-error", NONE, NONE_OK),
    ("wrong-transfer-type", NONE, bytes.fromhex("fefe 0001 01 00 00 00 0000 0000 0000")),
    ("zero-to-malformed", pose(length=24), answer(0x23)),
    ("zero-to-malformed", pose(index=2), answer(0x23)),
    ("zero-to-malformed", tolerance(math.nan), answer(0x25, 0x1002)),
    ("nan-zero", pose(x=math.nan), answer(0x23)),
    ("nan-zero", pose(index=1), answer(0x23, 0x1001)),
])
def test_broken_answers(name: str, request_: bytes, expected: bytes) -> None:
    with box(name) as b, connect(b) as s:
        s.sendall(request_)
        assert read(s, len(expected)) == expected


@pytest.mark.parametrize("name", ["dead", "no-resync"])
def test_silent_boxes(name: str) -> None:
    with box(name) as b, connect(b) as s:
        s.sendall(b"garbage" + NONE)
        assert silent(s)
        s.sendall(NONE)
        assert silent(s)


def test_drops_coalesced_answers_only_the_first_of_one_read() -> None:
    with box("drops-coalesced") as b, connect(b) as s:
        s.sendall(NONE + CYCLE_ON + CYCLE_OFF)
        assert read(s, 14) == NONE_OK
        assert silent(s)


def test_one_at_a_time_serves_the_second_connection_only_after_the_first_closes() -> None:
    with box("one-at-a-time") as b, connect(b) as first, connect(b) as second:
        first.sendall(NONE)
        assert read(first, 14) == NONE_OK
        second.sendall(NONE)
        assert silent(second)
        first.close()
        assert read(second, 14) == NONE_OK


def test_leaky_never_closes_and_resets_the_65th_connection() -> None:
    with box("leaky") as b:
        for _ in range(64):
            with connect(b) as s:
                s.sendall(NONE)
                assert read(s, 14) == NONE_OK
                s.shutdown(socket.SHUT_WR)
                assert not closed(s, 0.05)  # the box never closes its side
        try:
            s = connect(b)
        except ConnectionResetError:
            return  # the reset can beat connect() itself
        with s:  # accepted, then reset at once
            with contextlib.suppress(OSError):
                s.sendall(NONE)
            assert read(s, 14) == b""


def test_slow_bytes_and_late_cycle_on_miss_their_time() -> None:
    with box("slow-bytes") as b, connect(b) as s:
        s.sendall(NONE)
        assert len(read(s, 14, bound=1.0)) < 14
    with box("late-cycle-on") as b, connect(b) as s:
        s.sendall(CYCLE_ON)
        assert silent(s, 1.0)
        assert read(s, 14, bound=15) == answer(0x01)


@pytest.mark.parametrize("name", ["flood-random", "flood-headers"])
def test_flood_boxes_write_without_end(name: str) -> None:
    with box(name) as b, connect(b) as s:
        data = read(s, 1 << 20, bound=20)
        assert len(data) == 1 << 20
        if name == "flood-headers":
            assert data[:24] == bytes.fromhex("fefe00011023 01ffffff0000") * 2


# -- data and the command line ----------------------------------------------------------------------------------
def test_every_box_has_an_expectation_matching_its_defect() -> None:
    for name, variant in VARIANTS.items():
        exp = EXPECTATIONS[name]
        assert exp.role == "box" and exp.conforming == variant.conforming
        if not variant.conforming:
            assert exp.clauses[0] == variant.clause


def test_box_process_listens_answers_and_stops_on_sigterm() -> None:
    proc = subprocess.Popen([sys.executable, "-m", "tests.impls.box", "resync-fine", "--port", "0"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("listening tcp 127.0.0.1:")
        port = int(line.split()[2].rsplit(":", 1)[1])
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.sendall(NONE)
            assert read(s, 14) == NONE_OK
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(15) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)


def test_box_command_line_lists_and_refuses_unknown_variants() -> None:
    listing = subprocess.run([sys.executable, "-m", "tests.impls.box", "--list"], cwd=ROOT, capture_output=True,
                             text=True, timeout=60)
    assert listing.returncode == 0 and all(name in listing.stdout for name in VARIANTS)
    bad = subprocess.run([sys.executable, "-m", "tests.impls.box", "nope"], cwd=ROOT, capture_output=True,
                         text=True, timeout=60)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1


def test_close_on_garbage_answers_an_implausible_request_header_before_closing() -> None:
    with box("close-on-garbage") as b, connect(b) as s:
        s.sendall(bytes.fromhex("fefe 0001 01 25 02 54 faf7 0000") + b"/local")
        assert read(s, 14) == answer(0x25, 0x1002)
        assert closed(s)


# -- the knobs of the legal-choice space ---------------------------------------------------------------------------
RESULT_REQ = bytes.fromhex("fefe 0001 01 27 00 00 0000 0000 0000")
BAD_VERSION = bytes.fromhex("fefe 0002 01 00 00 00 0000 0000 0000")


def knob_box(**knobs: str) -> ThreadBox:
    return ThreadBox(knob_choices(knobs)).start()


def test_framing_is_chosen_per_kind_of_bad_field() -> None:
    f = Framer(framing=Framing(version="resume+12", transfer="trust"))
    f.feed(BAD_VERSION + bytes.fromhex("fefe 0001 10 00 00 00 0000 0000 0000") + NONE)
    events = list(f.events())
    assert isinstance(events[0], Rejected) and events[1] == Garbage(12)  # the version: rejected, 12 bytes skipped
    frames = [e.data for e in events if isinstance(e, Frame)]
    assert frames == [bytes.fromhex("fefe 0001 10 00 00 00 0000 0000 0000"), NONE]  # transfer 10: trusted whole
    closing = Framer(framing=Framing(garbage="close"))
    closing.feed(b"\x00" + NONE)
    assert list(closing.events())[-1] == Close() and closing.closed


@pytest.mark.parametrize(("knobs", "expected"), [
    ({"not_request": "error", "refusal_action": "echo", "refusal_code": "0001"}, answer(0x03, 0x0001)),
    ({"not_request": "error", "refusal_action": "00", "refusal_code": "1001"}, answer(0x00, 0x1001)),
])
def test_a_refusal_carries_the_echoed_action_or_00(knobs: dict[str, str], expected: bytes) -> None:
    with knob_box(**knobs) as b, connect(b) as s:
        s.sendall(bytes.fromhex("fefe 0001 01 03 00 00 0000 0000 0000"))
        assert read(s, 14) == expected


@pytest.mark.parametrize(("refusal", "expected"), [
    ("error-echo", answer(0x27, 0xFFFF)), ("error-00", answer(0x00, 0xFFFF)), ("silent", b""), ("close", b""),
])
def test_a_box_without_the_extension_refuses_27_each_legal_way(refusal: str, expected: bytes) -> None:
    with knob_box(extension="absent", ext_refusal=refusal) as b, connect(b) as s:
        s.sendall(RESULT_REQ)
        assert read(s, 14, bound=1.0) == expected
        if refusal == "close":
            assert closed(s)


def test_pieces_write_the_header_first_and_latency_keeps_the_order() -> None:
    choices = knob_choices({"writer": "pieces", "latency": "20ms", "cycle_on_latency": "0.6 time_out"})
    with ThreadBox(dataclasses.replace(choices, time_out=0.5)).start() as b, connect(b) as s:  # CycleOn: 0.3 s
        s.sendall(CYCLE_ON + NONE)
        t0 = time.monotonic()
        assert read(s, 28) == answer(0x01) + NONE_OK  # in request order, the NONE behind the slow CycleOn
        assert time.monotonic() - t0 >= 0.3


def test_first_not_ready_refuses_only_the_first_cycle_on() -> None:
    with knob_box(cycle_on_ready="first-not-ready") as b, connect(b) as s:
        s.sendall(CYCLE_ON)
        assert read(s, 14) == answer(0x01, 0x0001)
        s.sendall(CYCLE_ON)
        assert read(s, 14) == answer(0x01)


def test_a_separate_stream_port_serves_too() -> None:
    with knob_box(stream_port="separate") as b:
        assert b.stream_port is not None and b.stream_port != b.port
        with socket.create_connection(("127.0.0.1", b.stream_port), timeout=5) as s:
            s.sendall(pose())
            assert read(s, 14) == answer(0x23)


def test_a_closing_box_answers_then_ends_the_stream_cleanly() -> None:
    """A close with unread input is a reset, and a reset may drop answers not yet delivered (knobs
    framing_shape=resume+5 framing_garbage=close writer=bytes once lost the last bytes of a 1002 under load): the
    box shuts its side after the answers and reads what still comes until the peer closes (a race, so this checks
    the behaviour, not the loss)."""
    with knob_box(framing_shape="resume+5", framing_garbage="close", writer="bytes") as b, connect(b) as s:
        s.sendall(bytes.fromhex("fefe 0001 01 25 02 00 0005 0000 0000"))  # N=0: rejected, then garbage: close
        assert read(s, 14) == answer(0x25, 0x1002)
        assert closed(s)
        s.sendall(NONE)  # after the box's FIN it still reads (and drops) what comes
        assert s.recv(1) == b""


def test_an_echoed_27_refusal_echoes_whatever_the_refusal_action_of_other_frames() -> None:
    with knob_box(extension="absent", ext_refusal="error-echo", refusal_action="00") as b, connect(b) as s:
        s.sendall(RESULT_REQ)
        assert read(s, 14) == answer(0x27, 0xFFFF)
