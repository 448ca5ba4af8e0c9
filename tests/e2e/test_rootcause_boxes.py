"""Root causes end to end: the real ``run`` against two small boxes written here from PROTOCOL.md
(raw loopback sockets, ``struct``, no project code), each right but for one systematic defect:

* ``action-00``: answers every request as it should, but writes action 00 in every answer (A2);
* ``index-mod-16``: checks block indexes with a 4-bit counter (B3): a valid request of 17 or more
  blocks is refused, a wrong index at the 17th block accepted.

The first root cause of ``summary.json`` must name the fix, and every FAIL must belong to a root cause.
About 27 s each on a loaded 2-core machine (the full catalogue, extension E off: these boxes have none)."""

from __future__ import annotations

import json
import math
import os
import socket
import struct
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

import pytest

HEADER = struct.Struct(">HHBBBBHH")  # start word, version, transfer type, action, block type, N, L, error
SHAPES = {0x00: (0, 0), 0x01: (0, 0), 0x02: (0, 0), 0x23: (1, 25), 0x24: (1, 25), 0x25: (2, 5)}  # action: (type, L)


def _read(conn: socket.socket, n: int) -> bytes | None:
    data = b""
    while len(data) < n:
        chunk = conn.recv(n - len(data))
        if not chunk:
            return None
        data += chunk
    return data


def _error(action: int, btype: int, n: int, length: int, body: bytes, index_ok: Any) -> int:
    """0 for a well-formed request, else the action's error code (A3)."""
    code = 0x1002 if action == 0x25 else 0x1001
    want_type, want_len = SHAPES[action]
    if (btype, length) != (want_type, want_len) or (want_type and n == 0) or (not want_type and n):
        return code
    for i in range(n):
        block = body[i * length:(i + 1) * length]
        floats = struct.unpack(f">{(length - 1) // 4}f", block[1:])
        if not index_ok(i, block[0]) or not all(math.isfinite(f) for f in floats):
            return code
    return 0


class Box:
    """A thread per connection; bytes that are not a request close it (A5 allows it)."""

    def __init__(self, defect: str) -> None:
        self.defect = defect
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.stopping = False
        threading.Thread(target=self._accept, daemon=True).start()

    def index_ok(self, position: int, index: int) -> bool:
        expected = position & 0x0F if self.defect == "index-mod-16" else position  # first index 0 (B3)
        return index == expected

    def _accept(self) -> None:
        while not self.stopping:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        with conn, suppress(OSError):
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            while (head := _read(conn, 12)) is not None:
                start, version, transfer, action, btype, n, length, _ = HEADER.unpack(head)
                if start != 0xFEFE or version != 1 or transfer != 0x01:
                    return
                rest = _read(conn, n * length + 2)
                if rest is None:
                    return
                error = 0x0003 if action not in SHAPES else _error(action, btype, n, length, rest[:-2], self.index_ok)
                echoed = 0x00 if self.defect == "action-00" else action
                conn.sendall(HEADER.pack(0xFEFE, 1, 0x10, echoed, 0, 0, 0, error) + b"\x00\x00")

    def stop(self) -> None:
        self.stopping = True
        self.listener.close()


@contextmanager
def running(defect: str) -> Iterator[Box]:
    box = Box(defect)
    try:
        yield box
    finally:
        box.stop()


def run_suite(box: Box, tmp_path: Path) -> dict[str, Any]:
    command = [sys.executable, "-m", "conformance", "run", "--target", f"127.0.0.1:{box.port}", "--quiet",
               "--extension", "off", "--time-out", "2000", "--capture", "off",
               "--report-dir", str(tmp_path / "report"), "--pcap-dir", str(tmp_path / "pcaps")]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])})
    assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]
    [summary] = (tmp_path / "report").rglob("summary.json")
    doc: dict[str, Any] = json.loads(summary.read_text())
    return doc


def fails_without_cause(doc: dict[str, Any]) -> list[str]:
    return [c["id"] for c in doc["cases"] if c["verdict"] == "FAIL" and not c["root_cause"]]


@pytest.mark.impls(seconds=30)
def test_a_box_that_never_echoes_the_action_is_blamed_on_a2(tmp_path: Path) -> None:
    with running("action-00") as box:
        doc = run_suite(box, tmp_path)
    first = doc["root_causes"][0]
    assert (first["clauses"][0], first["level"], first["kind"]) == ("A2", "MUST", "action-not-echoed"), first
    assert len(first["cases"]) >= 20, first
    assert fails_without_cause(doc) == [], doc["root_causes"]


@pytest.mark.impls(seconds=30)
def test_a_box_counting_indexes_in_four_bits_is_blamed_on_b3(tmp_path: Path) -> None:
    with running("index-mod-16") as box:
        doc = run_suite(box, tmp_path)
    first = doc["root_causes"][0]
    assert (first["clauses"], first["level"], first["kind"]) == (["B3"], "MUST", "block-position"), first
    assert {"B1-01[255-pose]", "B2-01[255]"} <= set(first["cases"]), first
    assert fails_without_cause(doc) == [], doc["root_causes"]
    assert all(c["verdict"] in ("PASS", "SKIP", "INFORMATIONAL") for c in doc["cases"] if c["id"].startswith("B3-02"))
