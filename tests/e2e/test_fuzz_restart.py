"""A death that only a sequence causes: replayed on the restarted box, shrunk, written, replayed (fuzz/restart.py).

``SequenceDyingBox`` stops accepting connections when a tolerance request with two
blocks comes right after a register pose (the box's last request, on any connection):
no single case kills it, so the campaign's death search replays the history since the
last liveness check and shrinks it (ddmin) to the two requests.
"""

from __future__ import annotations

import json
import socket
import sys
import threading
from pathlib import Path

import pytest

from conformance.fuzz.config import CampaignConfig
from conformance.fuzz.death import Seen, find_killer
from conformance.fuzz.executor import Executor, alive
from conformance.fuzz.failure_files import write_vectors
from conformance.fuzz.replay import load_files, replay
from conformance.fuzz.restart import restart_command
from conformance.fuzz.strategies import Strategies
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.protocol import (
    DEFAULT_PROFILE,
    Action,
    Frame,
    StreamDecoder,
    TransferType,
    answer,
    encode_tcp,
    pose_blocks,
    request,
    tolerance_blocks,
)

pytestmark = pytest.mark.timeout(120)

NONE = encode_tcp(request(Action.NONE))
REGISTER = encode_tcp(request(Action.REGISTER_POSE, pose_blocks([(1.0, 2.0, 3.0, 0.0, 0.0, 0.0)])))
TOL2 = encode_tcp(request(Action.TOLERANCE, tolerance_blocks([0.5, 1.0])))
TOL1 = encode_tcp(request(Action.TOLERANCE, tolerance_blocks([0.5])))


def _close(server: socket.socket) -> None:
    """Stop listening (shutdown wakes the thread blocked in accept; close alone does not on Linux)."""
    try:
        server.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    server.close()


class SequenceDyingBox:
    """Stops accepting connections when, on one connection, a tolerance with two blocks follows a register pose
    (NONE requests in between do not count). ``restart()`` brings a fresh (still deadly) one up."""

    def __init__(self) -> None:
        self.port = 0
        self.restarts = 0
        self._start()

    def _start(self) -> None:
        server = self.server = socket.socket()
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind(("127.0.0.1", self.port))
        server.listen(16)
        self.port = server.getsockname()[1]
        threading.Thread(target=self._accept, args=(server,), daemon=True).start()

    def _accept(self, server: socket.socket) -> None:
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(server, conn), daemon=True).start()

    def _serve(self, server: socket.socket, conn: socket.socket) -> None:
        decoder = StreamDecoder(DEFAULT_PROFILE, TransferType.ROBOT_TO_BOX)
        prev = -1
        with conn:
            while data := conn.recv(65536):
                for event in decoder.feed(data):
                    if not isinstance(event, Frame):
                        continue
                    if event.action == Action.TOLERANCE and len(event.blocks) == 2 and prev == Action.REGISTER_POSE:
                        _close(server)
                    prev = prev if event.action == Action.NONE else int(event.action)
                    conn.sendall(encode_tcp(answer(event.action)))

    def restart(self) -> None:
        _close(self.server)
        self.restarts += 1
        self._start()


def test_a_death_only_a_sequence_causes_is_replayed_shrunk_and_written_whole(tmp_path: Path) -> None:
    box = SequenceDyingBox()
    try:
        cfg = CampaignConfig(target=Target("127.0.0.1", box.port), restart=box.restart, recover_s=2.0,
                             log=lambda _: None)
        s = Strategies(cfg.profile)
        ex = Executor(cfg.target, cfg.profile, Transcript("FUZZ-campaign-001"))
        cases = [s.case("valid", "", d, f"case {i}") for i, d in enumerate((NONE, TOL1, REGISTER, NONE, TOL2))]
        # NONE between them: no, the box's last request must be the register pose; run it as the campaign did
        window = [Seen(c, ex.run(c)) for c in cases[:3]] + [Seen(cases[4], ex.run(cases[4]))]
        assert not alive(ex.check_alive())
        death = find_killer(cfg, window, ex, number=2)
        assert death.back and alive(ex.check_alive())
        failure = death.failure
        assert failure.confirmed and failure.kind == "death"
        assert [c.wire for c in failure.cases] == [REGISTER, TOL2]  # shrunk from four cases to the two that kill
        assert "in this order" in failure.message
        path = write_vectors(tmp_path / "death.json", failure, cfg.profile, "a death sequence")
        doc = json.loads(path.read_text())
        assert [t["flags"] for t in doc["testGroups"][0]["tests"]] == [["KillSequence", "NewConnection"],
                                                                        ["KillSequence"]]
        assert set(doc["notes"]) == {"KillSequence", "NewConnection"}
        # replay carries the whole sequence: the box dies after the last step, and only then
        results = replay(load_files([path]), cfg.target, cfg.profile)
        assert [r.status for r in results] == ["OK", "FAIL"] and "R2" in results[1].why
    finally:
        _close(box.server)


def test_a_restart_command_runs_and_a_failing_one_is_an_error(tmp_path: Path) -> None:
    mark = tmp_path / "restarted"
    restart_command(f"{sys.executable} -c \"open(r'{mark}', 'w').write('x')\"", log=lambda _: None)()
    assert mark.read_text() == "x"
    with pytest.raises(RuntimeError, match="exited 3"):
        restart_command(f"{sys.executable} -c 'raise SystemExit(3)'", log=lambda _: None)()
