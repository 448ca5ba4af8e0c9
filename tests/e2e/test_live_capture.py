"""``--capture live`` (conformance/evidence/live.py).

The error path (no privileges) is tested everywhere by replacing the socket opener;
without root / CAP_NET_RAW it is also tested for real. The real capture runs only
with those privileges: it captures this test's own loopback traffic to 127.0.0.1 on
a port the test opened, next to a PcapRecorder fed from the transcript, and tshark
must find the same bytes per direction and the same iSight frames in both files.
"""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from conformance.evidence import live
from conformance.evidence.live import CaptureError, LiveCapture, default_bpf
from conformance.evidence.pcap import PcapRecorder
from conformance.harness.transcript import Transcript
from conformance.protocol import Action, request
from tests.e2e.test_pcap import LUA, Box, Client, pose

TSHARK = shutil.which("tshark")


def _has_cap_net_raw() -> bool:
    if os.geteuid() == 0:
        return True
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("CapEff:"):
                return bool(int(line.split()[1], 16) >> 13 & 1)  # CAP_NET_RAW = 13
    except OSError:
        pass
    return False


PRIVILEGED = _has_cap_net_raw()
needs_privileges = pytest.mark.skipif(not PRIVILEGED, reason="live capture needs root or CAP_NET_RAW")


def test_default_bpf():
    assert default_bpf(9004) == "tcp port 9004 or udp port 9004"
    assert LiveCapture("x.pcapng", port=1234).bpf == "tcp port 1234 or udp port 1234"
    assert LiveCapture("x.pcapng", bpf="tcp").bpf == "tcp"


@pytest.mark.parametrize(
    "exc",
    [PermissionError(errno.EPERM, "Operation not permitted"), OSError(errno.EACCES, "Permission denied")],
)
def test_without_privileges_a_clear_capture_error(monkeypatch, tmp_path, exc):
    def refuse(interface, bpf):
        raise exc

    monkeypatch.setattr(live, "_open_socket", refuse)
    cap = LiveCapture(tmp_path / "c.pcapng", port=9004)
    with pytest.raises(CaptureError, match=r"^live capture needs root or CAP_NET_RAW: "):
        cap.start()
    assert not (tmp_path / "c.pcapng").exists()  # nothing half-made
    assert cap.stop() == 0  # stopping a capture that never started is harmless


def test_other_open_errors_are_capture_errors(monkeypatch, tmp_path):
    def no_device(interface, bpf):
        raise OSError(errno.ENODEV, "No such device")

    monkeypatch.setattr(live, "_open_socket", no_device)
    with pytest.raises(CaptureError, match="no interface 'nope0'"):
        LiveCapture(tmp_path / "c.pcapng", interface="nope0").start()

    def bad_filter(interface, bpf):
        raise RuntimeError("Cannot set filter: syntax error")

    monkeypatch.setattr(live, "_open_socket", bad_filter)
    with pytest.raises(CaptureError, match="Cannot set filter"):
        LiveCapture(tmp_path / "c.pcapng", bpf="((").start()


@pytest.mark.skipif(PRIVILEGED, reason="runs only without root / CAP_NET_RAW")
def test_real_error_path_without_privileges(tmp_path):
    with pytest.raises(CaptureError, match="needs root or CAP_NET_RAW"):
        LiveCapture(tmp_path / "c.pcapng").start()


def _tshark_fields(path: Path, *fields: str, prefs: list[str] = ()) -> list[list[str]]:
    args = [TSHARK, "-n", "-r", str(path), "-X", f"lua_script:{LUA}", *prefs, "-T", "fields", "-E", "occurrence=a"]
    for f in fields:
        args += ["-e", f]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "lua" not in proc.stderr.lower(), proc.stderr
    return [line.split("\t") for line in proc.stdout.splitlines()]


def _follow(path: Path) -> tuple[bytes, bytes]:
    """(client bytes, server bytes) of TCP stream 0, reassembled by tshark."""
    proc = subprocess.run(
        [TSHARK, "-n", "-r", str(path), "-q", "-z", "follow,tcp,raw,0"], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    body = proc.stdout.split("=" * 67)[1]
    lines = [ln for ln in body.splitlines()[5:] if ln.strip()]
    client = b"".join(bytes.fromhex(ln) for ln in lines if not ln.startswith("\t"))
    server = b"".join(bytes.fromhex(ln.strip()) for ln in lines if ln.startswith("\t"))
    return client, server


@needs_privileges
@pytest.mark.tshark
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
def test_live_capture_of_own_loopback_traffic(tmp_path):
    box = Box("127.0.0.1")
    tr = Transcript(case_id="LIVE-001")
    synth = PcapRecorder.attach(tr, tmp_path / "synth.pcapng")
    cap = LiveCapture(tmp_path / "live.pcapng", interface="lo", port=box.port, case_id="LIVE-001")
    try:
        with cap:
            c = Client(tr, "127.0.0.1", box.port, "command")
            c.send_frames([request(Action.NONE)], "ping")
            c.expect(1)
            c.send_frames([pose(i) for i in range(200)], "200 poses")
            c.expect(200)
            big = [pose(i) for i in range(3000)]  # 117 kB: more than one loopback segment
            c.send_frames(big, "3000 poses")
            c.expect(3000)
            c.close()
            c.expect_eof()
            c.release()
    finally:
        tr.close()
        box.close()
    assert cap.error is None, cap.error
    assert cap.packets > 0
    conn = c.info.conn
    prefs = ["-o", f"isight.tcp_port:{box.port}"]
    for path in (cap.path, synth.path):
        client, server = _follow(path)
        assert client == tr.sent(conn), f"{path.name}: bytes we sent differ"
        assert server == tr.received(conn), f"{path.name}: bytes received differ"

    # every frame we sent and every answer, in order, in the live capture as in the synthesised one
    def pdus(path: Path) -> list[tuple[str, str]]:
        rows = _tshark_fields(path, "isight.transfer_type", "isight.action", prefs=prefs)
        return [(tt, a) for r in rows if r[0] for tt, a in zip(r[0].split(","), r[1].split(","))]

    live_pdus = pdus(cap.path)
    assert len([p for p in live_pdus if p[0] == "0x01"]) == len(c.tally.sent)
    assert len([p for p in live_pdus if p[0] == "0x10"]) == len(c.tally.received)
    assert sorted(live_pdus) == sorted(pdus(synth.path))
    # one copy of each packet (loopback shows every packet twice; the outgoing copy is dropped)
    rows = _tshark_fields(cap.path, "frame.number", "tcp.flags.syn", "tcp.flags.ack", "frame.comment", "frame.len")
    syns = [r for r in rows if r[1] in ("1", "True") and r[2] in ("0", "False")]
    assert len(syns) == 1, rows[:5]
    assert rows[0][3].startswith("LIVE-001: live capture on lo")
    assert max(int(r[4]) for r in rows) <= 65550  # whole frames, not cut at a 65535 snap length


@needs_privileges
@pytest.mark.skipif(TSHARK is None, reason="tshark is not installed (apt-get install tshark)")
def test_empty_live_capture_is_a_readable_file(tmp_path):
    cap = LiveCapture(tmp_path / "empty.pcapng", interface="lo", port=9)  # discard: nothing talks there
    cap.start()
    assert cap.stop() == 0
    assert _tshark_fields(cap.path, "frame.number") == []


@needs_privileges
def test_real_errors_with_privileges(tmp_path):
    with pytest.raises(CaptureError, match="nope0"):
        LiveCapture(tmp_path / "a.pcapng", interface="nope0").start()
    with pytest.raises(CaptureError, match="filter"):
        LiveCapture(tmp_path / "b.pcapng", bpf="tcp port (((").start()
