"""Every MUST clause has a case that FAILs when a box breaks it (the suite's own mutation test).

Each mutant is the bundled reference box with one planted defect (its ``decide`` patched,
or a knob), or a tiny scripted box for defects of the transport itself. The suite runs
against it, restricted to the cases that test the clause, in a subprocess with a time
limit; some case citing the clause must end FAIL. A static check first: every MUST
clause is cited by at least one MUST-level case.
"""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from conformance.endpoints.behaviour import BoxBehaviour, BoxConfig, Cycle, Decision, Reaction
from conformance.endpoints.loop import BoxThread
from conformance.model.verdicts import Level
from conformance.protocol import (
    Action,
    ErrorCode,
    Frame,
    ProtocolError,
    Transport,
    answer,
    encode,
    value_blocks,
)
from conformance.protocol.clauses import all_clauses
from tests.boxes import ScriptedBox, answering

pytestmark = pytest.mark.timeout(300)
ROOT = Path(__file__).resolve().parents[2]

#: MUST clauses of the registry that need no mutant of their own, and why (R6 is a SHOULD).
NO_MUTANT = {
    "B4": "its MUST part (binary32, big-endian) is F4's byte-order mutant; its NaN part is a SHOULD",
    "S2": "no mutant yet: CycleOn answered with a code other than 0000/0001 is judged by A3-02 (A3, S2)",
}
#: The registry's clauses whose level is MUST.
MUST_CLAUSES = [c.id for c in all_clauses().values() if c.level == "MUST" and c.id not in NO_MUTANT]

Transform = Callable[[BoxBehaviour, "Frame | ProtocolError", Decision], "Decision | None"]


def _raw(data: bytes, note: str = "planted defect") -> Decision:
    return Decision(Reaction.OK, answer(Action.NONE), data, data, note)


def _answer(frame: Frame) -> Decision:
    data = encode(frame)
    return Decision(Reaction.OK, frame, data, encode(frame, transport=Transport.UDP), "planted defect")


def _is_none_ok(event: Frame | ProtocolError) -> bool:
    return isinstance(event, Frame) and event.action == Action.NONE


def _patch_answers(change: Callable[[bytes], bytes], spare_none: bool = True) -> Transform:
    """Rewrite the bytes of every TCP answer (NONE answers spared: the baseline and the
    liveness checks stay healthy, so the defect shows in its own case)."""

    def transform(b: BoxBehaviour, event: Frame | ProtocolError, d: Decision) -> Decision | None:
        if d.tcp is None or (spare_none and _is_none_ok(event)):
            return None
        data = change(d.tcp)
        return Decision(d.reaction, d.frame, data, d.udp, "planted defect")

    return transform


def _udp_zero_to_everything(b: BoxBehaviour) -> None:
    """Answers every datagram 0000, a wrong CRC or a wrong length included (R7)."""
    original = b.receive_datagram

    def receive(data: bytes, trace: object = None) -> bytes | None:
        if len(data) >= 12 and data[:2] == b"\xfe\xfe":
            return encode(answer(Action(data[5]) if data[5] in Action._value2member_map_ else Action.NONE),
                          transport=Transport.UDP)
        return original(data, trace)  # type: ignore[arg-type]

    b.receive_datagram = receive  # type: ignore[method-assign]


def _zero_to(clauses: set[str], action: int | None = None) -> Transform:
    """Answer 0000 to malformed requests breaking one of ``clauses``."""

    def transform(b: BoxBehaviour, event: Frame | ProtocolError, d: Decision) -> Decision | None:
        if not isinstance(event, ProtocolError) or event.clause not in clauses or event.header is None:
            return None
        act = event.header.action if action is None else action
        head = struct.pack(">HHBBBBHH", 0xFEFE, 1, 0x10, act, 0, 0, 0, 0)
        return _raw(head + b"\x00\x00")

    return transform


def _when(predicate: Callable[[BoxBehaviour, Frame], bool], make: Callable[[Frame], Decision]) -> Transform:
    def transform(b: BoxBehaviour, event: Frame | ProtocolError, d: Decision) -> Decision | None:
        return make(event) if isinstance(event, Frame) and predicate(b, event) else None

    return transform


@contextmanager
def mutant_box(transform: Transform | None = None, config: BoxConfig | None = None,
               udp_patch: Callable[[BoxBehaviour], None] | None = None) -> Iterator[str]:
    box = BoxThread(config or BoxConfig(), host="127.0.0.1").start()
    try:
        if udp_patch is not None:
            box.call(lambda: udp_patch(box.behaviour))
        if transform is not None:

            def patch(b: BoxBehaviour) -> None:
                original = b.decide

                def decide(event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
                    d = original(event, transport)
                    return (transform(b, event, d) or d) if transport is Transport.TCP else d

                b.decide = decide  # type: ignore[method-assign]
                b.fast_path = False  # every frame through the patched decide()

            box.call(lambda: patch(box.behaviour))
        yield f"127.0.0.1:{box.tcp_port}|127.0.0.1:{box.udp_port}"
    finally:
        box.stop()


# -- scripted boxes for defects below the frame level ----------------------------------------


def _first_frame_per_read(conn: socket.socket) -> None:
    """Answers only the first frame of each read: coalesced frames are lost (R4/S6)."""
    from conformance.protocol import StreamDecoder, TransferType

    conn.settimeout(10)
    while data := conn.recv(65536):
        events = [e for e in StreamDecoder(expect=TransferType.ROBOT_TO_BOX).feed(data) if isinstance(e, Frame)]
        if events:
            conn.sendall(encode(answer(events[0].action)))


def _no_reassembly(conn: socket.socket) -> None:
    """Parses each read on its own: a frame split over reads is never answered (R3)."""
    _first_frame_per_read(conn)


DEAD = threading.Event()


def _dies_on_garbage(conn: socket.socket) -> None:
    """Answers requests; bytes that are not a frame kill the whole box (R2)."""
    from conformance.protocol import StreamDecoder, TransferType

    conn.settimeout(10)
    decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
    while not DEAD.is_set() and (data := conn.recv(65536)):
        for event in decoder.feed(data):
            if isinstance(event, Frame):
                conn.sendall(encode(answer(event.action)))
            else:
                DEAD.set()
                return


@contextmanager
def scripted(handler: Callable[[socket.socket], None], serial: bool = False, max_accepts: int | None = None,
             dies: bool = False) -> Iterator[str]:
    DEAD.clear()
    if not serial and max_accepts is None and not dies:
        with ScriptedBox(handler) as box:
            yield box.target
        return
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", 0))
    server.listen(512)
    server.settimeout(0.2)
    stop = threading.Event()

    def serve() -> None:
        accepted = 0
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            accepted += 1
            if (max_accepts is not None and accepted > max_accepts) or (dies and DEAD.is_set()):
                conn.close()  # stops serving new connections (S5/R5)
                continue
            if serial:
                try:
                    handler(conn)  # one connection at a time (S4)
                except OSError:
                    pass
                conn.close()
            else:
                threading.Thread(target=handler, args=(conn,), daemon=True).start()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(2)
        server.close()


def _slow_prog_idx(conn: socket.socket) -> None:
    """Implements E, but answers ProgIdx 700 ms late (E5 with time_out 500 ms)."""
    import time

    def respond(frame: Frame) -> bytes:
        if frame.action == Action.PROG_IDX:
            time.sleep(0.7)
            return encode(answer(Action.PROG_IDX, blocks=value_blocks([frame.blocks[0].value])))  # type: ignore[union-attr]
        if frame.action == Action.VISION_RESULT:
            return encode(answer(Action.VISION_RESULT, blocks=value_blocks([1])))
        return encode(answer(frame.action))

    answering(respond)(conn)


def _stop_after(n: int) -> Callable[[socket.socket], None]:
    """Answers the first ``n`` requests of a connection, then nothing (T2: lost answers)."""

    def handler(conn: socket.socket) -> None:
        count = [0]

        def respond(frame: Frame) -> bytes | None:
            count[0] += 1
            return encode(answer(frame.action)) if count[0] <= n or frame.action == Action.NONE else None

        answering(respond)(conn)

    return handler


# -- the matrix ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Mutant:
    clause: str
    defect: str
    cases: tuple[str, ...]
    box: Callable[[], contextmanager]  # type: ignore[type-arg]
    args: tuple[str, ...] = field(default=())


def _ref(transform: Transform | None = None, config: BoxConfig | None = None,
         udp_patch: Callable[[BoxBehaviour], None] | None = None) -> Callable[[], object]:
    return lambda: mutant_box(transform, config, udp_patch)


MUTANTS = [
    Mutant("F1", "answers start with fe ff", ("F1-*",), _ref(_patch_answers(lambda d: b"\xfe\xff" + d[2:], spare_none=False))),
    Mutant("F2", "answers carry version 00 02", ("F2-*",), _ref(_patch_answers(lambda d: d[:2] + b"\x00\x02" + d[4:], spare_none=False))),
    Mutant("F3", "answers carry transfer type 01", ("F3-*",), _ref(_patch_answers(lambda d: d[:4] + b"\x01" + d[5:]))),
    Mutant("F4", "the error code of answers written little-endian", ("F4-*",),
           _ref(_patch_answers(lambda d: d[:10] + d[10:12][::-1] + d[12:] if d[10:12] != b"\x00\x00" else d))),
    Mutant("F5", "a stray byte after every NONE answer", ("F5-*",), _ref(_patch_answers(lambda d: d + b"\x00", spare_none=False))),
    Mutant("F6", "TCP answers carry check 12 34", ("F6-*",), _ref(_patch_answers(lambda d: d[:-2] + b"\x12\x34"))),
    Mutant("F7", "UDP answers carry a wrong CRC", ("F7-*",), _ref(config=BoxConfig()), ("--crc", "xmodem")),
    Mutant("B1", "several-pose requests answered 1001", ("B1-*",),
           _ref(_when(lambda b, f: f.action == Action.POSE and len(f.blocks) > 1, lambda f: _answer(answer(f.action, ErrorCode.POSE_ERROR))))),
    Mutant("B2", "several-tolerance requests answered 1002", ("B2-*",),
           _ref(_when(lambda b, f: f.action == Action.TOLERANCE and len(f.blocks) > 1,
                      lambda f: _answer(answer(f.action, ErrorCode.TOLERANCE_ERROR))))),
    Mutant("B3", "wrong indexes answered 0000", ("B3-*",), _ref(_zero_to({"B3"}))),
    Mutant("B5", "shape errors answered 0000", ("B5-*",), _ref(_zero_to({"B5", "B1", "B2"}))),
    Mutant("A1", "CycleOff answered twice", ("A1-0*",),
           _ref(_patch_answers(lambda d: d + d if d[5] == Action.CYCLE_OFF else d))),
    Mutant("A2", "pose answers carry a pose block", ("A2-*",),
           _ref(_patch_answers(lambda d: d[:6] + b"\x01\x01\x00\x19" + d[10:12] + bytes(25) + b"\x00\x00" if d[5] == Action.POSE else d))),
    Mutant("A3", "malformed poses answered 0000", ("A3-*",), _ref(_zero_to({"B3", "B5", "B1"}))),
    Mutant("A4", "NONE answered 0001", ("T1-00", "A4-*"),
           _ref(_when(lambda b, f: f.action == Action.NONE, lambda f: _answer(answer(Action.NONE, ErrorCode.NOT_READY))))),
    Mutant("A5", "unknown actions answered 0000", ("A5-01*",), _ref(_zero_to({"A5", "F2", "F3"}))),
    Mutant("S1", "CycleOff answered as NONE", ("S1-*",),
           _ref(_when(lambda b, f: f.action == Action.CYCLE_OFF, lambda f: _answer(answer(Action.NONE))))),
    Mutant("S3", "poses outside a cycle answered 1001", ("S3-*",),
           _ref(_when(lambda b, f: f.action == Action.POSE and b.state is Cycle.IDLE,
                      lambda f: _answer(answer(Action.POSE, ErrorCode.POSE_ERROR))))),
    Mutant("S4", "one connection at a time", ("S4-01",), lambda: scripted(answering(), serial=True), ("--time-out", "1500")),
    Mutant("S5", "stops accepting after 40 connections", ("S5-01",), lambda: scripted(answering(), max_accepts=40), ("--time-out", "1000")),
    Mutant("S6", "only the first frame of each read is answered", ("S6-*",), lambda: scripted(_first_frame_per_read), ("--time-out", "800")),
    Mutant("T1", "every answer 700 ms late (time_out 500 ms)", ("T1-*",), _ref(config=BoxConfig(latency_ms=700)), ("--time-out", "500")),
    Mutant("T2", "the stream goes unanswered after 20 poses", ("T2-*",), lambda: scripted(_stop_after(20)),
           ("--time-out", "800", "--stream-seconds", "1")),
    Mutant("R1", "invalid vectors answered 0000", ("R1-10*",), _ref(_zero_to({"B3", "B5", "B1", "B2", "A5", "F2", "F3", "F6"}))),
    Mutant("R3", "a frame split over reads is never answered", ("R3-01*",), lambda: scripted(_no_reassembly), ("--time-out", "800")),
    Mutant("R4", "only the first frame of each read is answered", ("R4-*",), lambda: scripted(_first_frame_per_read), ("--time-out", "800")),
    Mutant("R5", "stops accepting after 100 connections", ("R5-*",), lambda: scripted(answering(), max_accepts=100), ("--time-out", "1000")),
    Mutant("R2", "the box dies on garbage", ("R2-01*",), lambda: scripted(_dies_on_garbage, dies=True), ("--time-out", "800")),
    Mutant("R7", "wrong-CRC datagrams answered 0000", ("R7-*",), _ref(udp_patch=_udp_zero_to_everything)),
    Mutant("E1", "negative program indexes answered 400", ("E1-*",),
           _ref(_when(lambda b, f: f.action == Action.PROG_IDX and f.blocks[0].value < 0,  # type: ignore[union-attr]
                      lambda f: _answer(answer(Action.PROG_IDX, blocks=value_blocks([400])))))),
    Mutant("E2", "ProgIdx answered without a block", ("E2-*",),
           _ref(_when(lambda b, f: f.action == Action.PROG_IDX, lambda f: _raw(encode(answer(Action.NONE))[:5] + b"\x26" + bytes(8))))),
    Mutant("E3", "result code 404 sent", ("E3-*",),
           _ref(_when(lambda b, f: f.action == Action.VISION_RESULT,
                      lambda f: _answer(answer(Action.VISION_RESULT, blocks=value_blocks([404])))))),
    Mutant("E4", "result request answered 0", ("E4-*", "SEQ-E4"),
           _ref(_when(lambda b, f: f.action == Action.VISION_RESULT,
                      lambda f: _answer(answer(Action.VISION_RESULT, blocks=value_blocks([0])))))),
    Mutant("E5", "ProgIdx answered 700 ms late (time_out 500 ms)", ("E5-*",), lambda: scripted(_slow_prog_idx),
           ("--time-out", "500")),
]


def run_cases(tmp_path: Path, target: str, globs: tuple[str, ...], args: tuple[str, ...]) -> dict[str, dict]:
    tcp, _, udp = target.partition("|")
    cmd = [sys.executable, "-m", "conformance", "run", "--quiet", "--capture", "off", "--target", tcp,
           "--report-dir", str(tmp_path), *args]
    if udp:
        cmd += ["--udp-target", udp]
    for glob in globs:
        cmd += ["--cases", glob]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=240, cwd=tmp_path)
    summary = tmp_path / "summary.json"
    assert summary.is_file(), f"no summary (exit {proc.returncode}): {proc.stdout[-2000:]} {proc.stderr[-2000:]}"
    assert "Traceback" not in proc.stderr, proc.stderr
    return {c["id"]: c for c in json.loads(summary.read_text())["cases"]}


def test_every_must_clause_is_cited_by_a_must_case() -> None:
    from conformance.commands.run_flow import collect
    from conformance.runtime.settings import SuiteSettings

    cases = collect(SuiteSettings())
    assert cases, "the catalogue did not load"
    cited = {c for info in cases if info.level is Level.MUST for c in info.clauses}
    assert not set(MUST_CLAUSES) - cited, f"MUST clauses no MUST case cites: {sorted(set(MUST_CLAUSES) - cited)}"
    assert {m.clause for m in MUTANTS} >= set(MUST_CLAUSES), "every MUST clause needs a mutant"


@pytest.mark.parametrize("mutant", MUTANTS, ids=lambda m: m.clause)
def test_a_box_breaking_the_clause_fails_a_case_citing_it(tmp_path: Path, mutant: Mutant) -> None:
    with mutant.box() as target:
        results = run_cases(tmp_path, target, mutant.cases, mutant.args)
    failing = {cid: c for cid, c in results.items() if c["verdict"] == "FAIL"}
    citing = {cid for cid, c in failing.items() if mutant.clause in c["clauses"]}
    assert citing, (f"{mutant.clause} ({mutant.defect}): no FAIL case cites it; verdicts: "
                    f"{ {cid: c['verdict'] for cid, c in results.items()} }")
    assert not any(c["verdict"] == "ERROR" for c in results.values()), "the suite erred on a broken box"
