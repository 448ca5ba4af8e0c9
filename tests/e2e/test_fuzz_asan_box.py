"""The box's last words from a C box built with AddressSanitizer (skipped without a C compiler).

``tests/impls/asan_box.c`` has one heap overflow: a tolerance request of exactly 7 blocks writes 5 bytes past
a 30-byte buffer. Built plainly the box answers it and lives (the bytes land in malloc's slack); built with
``-fsanitize=address,undefined`` it dies, and ``fuzz --restart-cmd`` reports R2 with ASan's headline.
"""

from __future__ import annotations

import json
import shutil
import socket
import struct
import subprocess
from pathlib import Path

import pytest

from conformance.commands import main

pytestmark = [pytest.mark.timeout(400), pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")]

SOURCE = Path(__file__).resolve().parents[1] / "impls" / "asan_box.c"
NONE = bytes.fromhex("fefe000101000000000000000000")


def build(out: Path, *flags: str) -> Path | None:
    done = subprocess.run(["gcc", "-O1", "-g", *flags, "-pthread", str(SOURCE), "-o", str(out)], capture_output=True,
                          timeout=120, check=False)
    return out if done.returncode == 0 else None


@pytest.fixture(scope="module")
def boxes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("asan")
    plain = build(tmp / "plain_box")
    assert plain is not None, "gcc could not build tests/impls/asan_box.c"
    sanitized = build(tmp / "asan_box", "-fsanitize=address,undefined", "-fno-omit-frame-pointer")
    if sanitized is None:
        pytest.skip("gcc has no AddressSanitizer runtime here")
    return {"plain": plain, "asan": sanitized}


def tolerance(n: int) -> bytes:
    body = b"".join(bytes([i]) + struct.pack(">f", 0.5) for i in range(n))
    return struct.pack(">HHBBBBHH", 0xFEFE, 1, 1, 0x25, 2, n, 5, 0) + body + b"\0\0"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_built_plainly_the_overflow_shows_nothing_on_the_wire(boxes: dict[str, Path]) -> None:
    proc = subprocess.Popen([str(boxes["plain"]), "0"], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        port = int(proc.stdout.readline().split()[1])
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.settimeout(5)
            for n in (6, 7, 8):
                s.sendall(tolerance(n))
                assert s.recv(64) == bytes.fromhex("fefe000110250000000000000000")
        with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
            s.settimeout(5)
            s.sendall(NONE)
            assert s.recv(64) == bytes.fromhex("fefe000110000000000000000000")
        assert proc.poll() is None
    finally:
        proc.kill()
        proc.wait(10)


def test_built_with_asan_the_fuzzer_reports_r2_with_the_sanitizer_headline(
        boxes: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port()
    code = main(["fuzz", "--target", f"127.0.0.1:{port}", "--restart-cmd", f"{boxes['asan']} {port}",
                 "--stateful-share", "0", "--duration", "240", "--until-first", "--extension", "off",
                 "--database", "none", "--seed", "3", "--report-dir", str(tmp_path / "r"),
                 "--pcap-dir", str(tmp_path / "p"), "--quiet"])
    out = capsys.readouterr().out
    assert code == 1, out
    summary = json.loads((tmp_path / "r" / "fuzz-summary.json").read_text())
    failure = summary["failures"][0]
    assert failure["kind"] == "death" and failure["clauses"][0] == "R2" and failure["confirmed"] is True
    words = failure["last_words"]
    assert words["kind"] == "asan" and words["exit_status"] == 1
    assert words["headline"].startswith("AddressSanitizer: heap-buffer-overflow (WRITE of size 35) in store_tolerances")
    assert words["headline"].endswith("asan_box.c:59")
    killer = failure["cases"][0]["hex"]
    assert "fefe00010125020700" in killer  # a tolerance request of exactly 7 blocks
    first = next(line for line in out.splitlines() if line.startswith("  FAIL"))
    assert first.startswith("  FAIL 1 [R2"), first
    assert "box: the box (incarnation 1" in out and "AddressSanitizer: heap-buffer-overflow" in out
    notes = json.loads(Path(failure["vector"]).read_text())["notes"]
    assert "ERROR: AddressSanitizer: heap-buffer-overflow" in notes["BoxLastWords"]
