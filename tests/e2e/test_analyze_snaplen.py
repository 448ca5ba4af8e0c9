"""analyze on a capture cut by the capture tool's snap length (``tcpdump -s 64``), issue 36 item 5.

A session of the suite's own robot and box is recorded (tests/analyze_util.py), then every packet
is cut after 64 bytes as the capture tool would (caplen < len): 10 bytes of each iSight frame are
left behind the Ethernet, IP and TCP headers. The frames cut short are INCONCLUSIVE (F5) with the
reason, and the session is judged on what can be read: the headers, the order and the timing.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from scapy.utils import rdpcap

from conformance.analyze import AnalyzeConfig, analyze, build_cases
from conformance.endpoints.behaviour import BoxConfig
from conformance.model.verdicts import Verdict
from tests.analyze_util import FAST, record

pytestmark = pytest.mark.timeout(120)

LOOSE = AnalyzeConfig(profile=FAST, rate_tolerance=0.5, jitter_tolerance=3.0)
SNAPLEN = 64


def cut_capture(src: Path, dst: Path, snaplen: int = SNAPLEN) -> int:
    """``src`` rewritten as a classic pcap whose packets keep their first ``snaplen`` bytes (their length
    on the wire unchanged, as a capture tool writes it); how many packets were cut."""
    cut = 0
    with open(dst, "wb") as fh:
        fh.write(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, snaplen, 1))  # Ethernet
        for pkt in rdpcap(str(src)):
            raw = bytes(pkt)
            sec, usec = divmod(round(float(pkt.time) * 1e6), 1_000_000)
            fh.write(struct.pack("<IIII", sec, usec, min(len(raw), snaplen), len(raw)) + raw[:snaplen])
            cut += len(raw) > snaplen
    return cut


def cases(path: Path, config: AnalyzeConfig = LOOSE) -> dict:
    return {c.id: c for c in build_cases(analyze(path, config))}


def recorded_and_cut(tmp_path: Path, name: str, **kwargs) -> Path:
    whole, _ = record(tmp_path / f"{name}.pcapng", **kwargs)
    cut = tmp_path / f"{name}-cut.pcap"
    assert cut_capture(whole, cut) >= 10  # every frame-carrying packet was cut
    return cut


def test_a_conforming_session_cut_at_64_bytes_is_judged_on_what_can_be_read(tmp_path: Path) -> None:
    c = cases(recorded_and_cut(tmp_path, "clean"))
    assert {k: x.message for k, x in c.items() if x.verdict is Verdict.FAIL} == {}
    assert c["OBS-S1-robot"].verdict is Verdict.PASS, c["OBS-S1-robot"].message  # the order, from the headers
    for case_id in ("OBS-A1-box", "OBS-A2-box", "OBS-T1-box", "OBS-T2-robot", "OBS-F3-robot", "OBS-F3-box"):
        assert c[case_id].verdict is Verdict.PASS, (case_id, c[case_id].message)
    for side in ("robot", "box"):  # the cut frames: INCONCLUSIVE, with the reason
        cut = c[f"OBS-F5-{side}"]
        assert cut.verdict is Verdict.INCONCLUSIVE and "cut by the capture's snap length after 10 byte(s)" in cut.message
    # what the capture does not hold is not judged: the answers' codes, the blocks, the check field
    for case_id in ("OBS-S3-box", "OBS-A3-box", "OBS-B1-robot", "OBS-B3-robot", "OBS-F6-robot", "OBS-F6-box"):
        assert c[case_id].verdict is not Verdict.PASS, (case_id, c[case_id].message)


def test_a_robot_out_of_order_is_still_failed_on_s1_in_a_cut_capture(tmp_path: Path) -> None:
    steps = ("connect", "cycle_on", "send_pos_on", "trajectory", "cycle_off", "send_pos_off", "disconnect")
    c = cases(recorded_and_cut(tmp_path, "order", robots=[{"steps": steps}]))
    assert c["OBS-S1-robot"].verdict is Verdict.FAIL, c["OBS-S1-robot"].message
    assert not {k for k, x in c.items() if x.verdict is Verdict.FAIL and k.endswith("-box")}


def test_a_slow_box_is_still_failed_on_t1_in_a_cut_capture(tmp_path: Path) -> None:
    path = recorded_and_cut(tmp_path, "slow", box=BoxConfig(profile=FAST, latency_ms=300))
    c = cases(path, AnalyzeConfig(profile=FAST.replace(time_out_ms=200), rate_tolerance=0.5, jitter_tolerance=3.0))
    assert c["OBS-T1-box"].verdict is Verdict.FAIL and "bound is 200 ms" in c["OBS-T1-box"].message
