"""Self-test of the B1–B5 / A1–A5 cases and the golden-vector replay: broken boxes fail them.

Each broken box is a small threaded TCP server (the reference behaviour with one
clause broken). The cases run against it in a subprocess (``pytest --pyargs ...
--target``, bounded by a timeout) and the verdicts are read from ``summary.json``.
The bundled reference box must pass every case: no FAIL, NON-STRICT or ERROR.
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from conformance.endpoints.behaviour import BoxBehaviour, BoxConfig
from conformance.protocol import (
    DEFAULT_PROFILE,
    EXTENSION_ACTIONS,
    Action,
    Frame,
    Header,
    ProtocolError,
    StreamDecoder,
    TransferType,
    answer,
    encode,
    encode_raw,
    pose_blocks,
)

MINE = ["conformance.cases.blocks", "conformance.cases.actions", "conformance.cases.vector_replay"]
BAD = ("FAIL", "NON-STRICT", "ERROR")
#: the case IDs these modules define (the plugin may add an "always" baseline case of its own)
MY_IDS = ("B1-", "B2-", "B3-", "B4-", "B5-", "A1-", "A2-", "A3-", "A4-", "A5-", "R1-10", "R1-11")


class BrokenBox:
    """The reference behaviour over plain sockets, broken the way ``mode`` says:

    ``ok-all`` answers everything (malformed too) with its action and 0000;
    ``pose-0001`` answers malformed 23/24 with 0001 instead of 1001;
    ``twice`` sends every answer twice; ``reorder`` reverses the answers of one read;
    ``blocks`` puts a pose block in every answer but NONE's; ``tt01`` answers all but NONE
    with transfer type 01; ``none-0001`` answers NONE with 0001 unless it is the first
    frame of its connection; ``no-ext-26-ok`` lacks E (closes on 27) but answers 26 with 0000.

    NONE on a fresh connection stays right in every mode: the plugin's session baseline
    (and the R2 liveness check) is a NONE on a fresh connection, and a box that fails it
    has every case INCONCLUSIVE instead of judged.
    """

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self.behaviour = BoxBehaviour(BoxConfig(extension=mode != "no-ext-26-ok"))
        self.lock = threading.Lock()
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        threading.Thread(target=self._accept, daemon=True).start()

    def close(self) -> None:
        self.server.close()

    def _accept(self) -> None:
        while True:
            try:
                sock, _ = self.server.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(sock,), daemon=True).start()

    def _serve(self, sock: socket.socket) -> None:
        decoder = StreamDecoder(DEFAULT_PROFILE, TransferType.ROBOT_TO_BOX)
        frames = 0
        with sock:
            while True:
                try:
                    data = sock.recv(65536)
                except OSError:
                    return
                decoder.receive_data(data)
                out: list[bytes] = []
                close = False
                for event in decoder.events():
                    replies, close = self._reply(event, first=frames == 0)
                    frames += 1
                    out += replies
                    if close:
                        break
                if self.mode == "reorder":
                    out.reverse()
                try:
                    sock.sendall(b"".join(out))
                except OSError:
                    return
                if close or not data:
                    return

    def _reply(self, event: Frame | ProtocolError, first: bool) -> tuple[list[bytes], bool]:
        with self.lock:
            decision = self.behaviour.decide(event)
            bad_action = self.behaviour.request_action(event) if isinstance(event, ProtocolError) else None
        base = [decision.tcp] if decision.tcp else []
        mode = self.mode
        if mode == "ok-all":
            if isinstance(event, Frame):
                action = int(event.action)
            else:
                action = event.header.action if event.header is not None else 0
            return [encode_raw(Header(transfer_type=0x10, action=action))], False
        if mode == "pose-0001" and bad_action in (Action.POSE, Action.REGISTER_POSE):
            return [encode(answer(bad_action, 0x0001))], False
        if mode == "twice":
            return base * 2, decision.close
        frame = decision.frame
        spared = frame is not None and frame.action in (Action.NONE, *EXTENSION_ACTIONS)
        if mode == "blocks" and frame is not None and not spared:
            return [encode(answer(frame.action, frame.error_code, pose_blocks([(0.0,) * 6])))], False
        if mode == "tt01" and not spared:
            return [b[:4] + b"\x01" + b[5:] for b in base], decision.close
        if mode == "none-0001" and isinstance(event, Frame) and event.action == Action.NONE and not first:
            return [encode(answer(Action.NONE, 0x0001))], False
        if mode == "no-ext-26-ok":
            code = event.action if isinstance(event, Frame) else event.header.action if event.header else None
            if code == Action.PROG_IDX:
                return [encode_raw(Header(transfer_type=0x10, action=Action.PROG_IDX))], False
            if code == Action.VISION_RESULT:
                return [], True
        return base, decision.close


def run_cases(tmp: Path, modules: list[str], target: str | None = None, cases: tuple[str, ...] = (),
              extra: tuple[str, ...] = ()) -> dict[str, dict[str, Any]]:
    """Run the cases in a subprocess; ``{case id: summary entry}``."""
    report = tmp / "report"
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-o", "addopts=",
           "--pyargs", *modules, "--report-dir", str(report), *extra]
    if target:
        cmd += ["--target", target]
    cmd += [f"--cases={glob}" for glob in cases]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=50, cwd=tmp)
    summary = report / "summary.json"
    assert summary.is_file(), f"no summary.json; pytest said:\n{proc.stdout[-3000:]}\n{proc.stderr[-2000:]}"
    return {c["id"]: c for c in json.loads(summary.read_text())["cases"]}


@pytest.fixture
def broken(request: pytest.FixtureRequest) -> Iterator[BrokenBox]:
    box = BrokenBox(request.param)
    yield box
    box.close()


def _verdicts(results: dict[str, dict[str, Any]], prefix: str) -> dict[str, str]:
    found = {cid: c["verdict"] for cid, c in results.items() if cid.startswith(prefix) and c["verdict"] != "SKIP"}
    assert found, f"no case {prefix}* ran; ran: {sorted(results)}"
    return found


def _assert_failed(results: dict[str, dict[str, Any]], prefix: str, verdict: str = "FAIL") -> None:
    """Every case under ``prefix`` ended ``verdict`` (or SKIP: not applicable), naming one of its own clauses."""
    for cid, c in results.items():
        if not cid.startswith(prefix) or c["verdict"] == "SKIP":
            continue
        assert c["verdict"] == verdict, f"{cid}: {c['verdict']} {c['message']}"
        clause = c["message"].split(":", 1)[0].split("/")[0]
        assert clause in c["clauses"], f"{cid}: verdict names clause {clause!r}, not one of {c['clauses']}"
    _verdicts(results, prefix)


# -- the reference box passes ---------------------------------------------------------------------


def test_reference_box_passes_everything(tmp_path: Path) -> None:
    results = {cid: c for cid, c in run_cases(tmp_path, MINE).items() if cid.startswith(MY_IDS)}
    bad = {cid: (c["verdict"], c["message"]) for cid, c in results.items() if c["verdict"] in BAD}
    assert not bad
    assert len(results) > 150
    assert results["A1-01"]["verdict"] == "PASS"
    assert results["R1-10[tcp-robot-to-box-tc59]"]["verdict"] == "PASS"


# -- broken boxes ------------------------------------------------------------------------------------


@pytest.mark.parametrize("broken", ["ok-all"], indirect=True)
def test_zero_to_everything_fails_must_cases(tmp_path: Path, broken: BrokenBox) -> None:
    results = run_cases(tmp_path, MINE, f"127.0.0.1:{broken.port}",
                        ("B3-02*", "B5-*", "A3-01*", "A5-01*", "R1-10*", "B1-02*", "B2-02*"))
    for prefix in ("B1-02", "B2-02", "B3-02", "B5-01", "A3-01", "A5-01", "R1-10"):
        _assert_failed(results, prefix)
    assert results["R1-10[tcp-robot-to-box-tc66]"]["verdict"] == "FAIL"  # cut short, then answered 0000


@pytest.mark.parametrize("broken", ["no-ext-26-ok"], indirect=True)
def test_unknown_extension_action_answered_zero_fails_a5(tmp_path: Path, broken: BrokenBox) -> None:
    results = run_cases(tmp_path, ["conformance.cases.actions"], f"127.0.0.1:{broken.port}", ("A5-02*",))
    _assert_failed(results, "A5-02[26-prog-idx]")
    assert results["A5-02[27-vision-result]"]["verdict"] == "PASS"  # closing is allowed (A5)


@pytest.mark.parametrize("broken", ["pose-0001"], indirect=True)
def test_wrong_error_code_is_non_strict(tmp_path: Path, broken: BrokenBox) -> None:
    results = run_cases(tmp_path, MINE, f"127.0.0.1:{broken.port}", ("A3-*", "B3-02*", "B5-01*", "R1-10*"))
    _assert_failed(results, "A3-01[pose]", "NON-STRICT")
    _assert_failed(results, "A3-01[register-pose]", "NON-STRICT")
    _assert_failed(results, "B3-02[gap-pose]", "NON-STRICT")
    _assert_failed(results, "R1-10[tcp-robot-to-box-tc59]", "NON-STRICT")
    assert results["A3-01[tolerance]"]["verdict"] == "PASS"
    assert results["B5-01[tolerance-N0]"]["verdict"] == "PASS"
    assert not [cid for cid, c in results.items() if c["verdict"] in ("FAIL", "ERROR")]


@pytest.mark.parametrize("broken", ["twice", "reorder"], indirect=True)
def test_extra_or_reordered_answers_fail_a1(tmp_path: Path, broken: BrokenBox) -> None:
    results = run_cases(tmp_path, ["conformance.cases.actions"], f"127.0.0.1:{broken.port}", ("A1-*", "A4-*"))
    _assert_failed(results, "A1-01")
    if broken.mode == "twice":
        _assert_failed(results, "A1-02")
    else:  # one request at a time: nothing to reorder
        assert results["A1-02"]["verdict"] == "PASS"


@pytest.mark.parametrize("broken", ["blocks", "tt01"], indirect=True)
def test_answer_shape_fails_a2(tmp_path: Path, broken: BrokenBox) -> None:
    modules = ["conformance.cases.frame", "conformance.cases.actions"]
    results = run_cases(tmp_path, modules, f"127.0.0.1:{broken.port}", ("A2-*", "F3-01"))
    for param in ("cycle-on-off", "pose", "register-pose", "tolerance", "malformed-pose"):
        _assert_failed(results, f"A2-01[{param}]")
    assert results["A2-01[none]"]["verdict"] == "PASS"  # NONE answers are spared (see BrokenBox)
    if broken.mode == "tt01":
        assert results["F3-01"]["verdict"] == "FAIL", results["F3-01"]


@pytest.mark.parametrize("broken", ["none-0001"], indirect=True)
def test_none_answered_error_fails_a4(tmp_path: Path, broken: BrokenBox) -> None:
    results = run_cases(tmp_path, ["conformance.cases.actions"], f"127.0.0.1:{broken.port}", ("A4-*", "A2-01?pose?"))
    _assert_failed(results, "A4-01")
    assert results["A2-01[pose]"]["verdict"] == "PASS"  # the shape of a NONE 0001 answer is A4's business


def test_missing_vectors_give_one_skip(tmp_path: Path) -> None:
    """Without the vector directory the replay collects one SKIP per kind instead of crashing."""
    code = (
        "import conformance.evidence.vectors_file as v, pathlib; v.REPO_VECTORS = pathlib.Path('/nonexistent');"
        "import sys, pytest; sys.exit(pytest.main(sys.argv[1:]))"
    )
    report = tmp_path / "report"
    proc = subprocess.run(
        [sys.executable, "-c", code, "-p", "no:cacheprovider", "-q", "-o", "addopts=", "--pyargs", "conformance.cases.vector_replay",
         "--report-dir", str(report)], capture_output=True, text=True, timeout=30, cwd=tmp_path)
    cases = {c["id"]: c for c in json.loads((report / "summary.json").read_text())["cases"]}
    assert set(cases) == {"A1-10[no-vectors]", "R1-10[no-vectors]", "R1-11[no-vectors]"}, proc.stdout[-2000:]
    assert all(c["verdict"] == "SKIP" and "/nonexistent" in c["message"] for c in cases.values())
