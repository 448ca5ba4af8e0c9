"""Reading capture files (conformance/analyze/capture.py): pcap and pcapng (also gzip'd and
nanosecond pcap), Wireshark's frame numbers and time stamps, and one clear CaptureError
for a file that is empty, not a capture, or cut short."""

from __future__ import annotations

import gzip
import struct

import pytest

from conformance.analyze.capture import CaptureError, CaptureReader
from tests.analyze_util import Capture, canonical


def _capture(tmp_path, fmt="pcapng"):
    cap = Capture(t0=1_700_000_123.25, step=0.5)
    canonical(cap, poses=3)
    return cap, cap.write(tmp_path / f"c.{fmt}", fmt=fmt)


@pytest.mark.parametrize("fmt", ["pcap", "pcapng"])
def test_every_packet_with_its_frame_number_time_and_bytes(tmp_path, fmt):
    cap, path = _capture(tmp_path, fmt)
    with CaptureReader(path) as reader:
        got = list(reader.packets())
        assert reader.format == fmt and reader.truncated is None
    assert [n for n, *_ in got] == list(range(1, len(cap.packets) + 1))
    assert [bytes(data) for *_, data in got] == [bytes(p) for p in cap.packets]
    assert [ts for _, ts, _, _ in got] == pytest.approx([float(p.time) for p in cap.packets], abs=1e-6)
    assert {lt for _, _, lt, _ in got} == {1}
    assert reader.first_ts == pytest.approx(1_700_000_123.75)


def test_a_gzipped_capture_is_read(tmp_path):
    cap, path = _capture(tmp_path)
    gz = tmp_path / "c.pcapng.gz"
    gz.write_bytes(gzip.compress(path.read_bytes()))
    with CaptureReader(gz) as reader:
        assert reader.compressed and reader.format == "pcapng"
        assert len(list(reader.packets())) == len(cap.packets)


def test_nanosecond_pcap_time_stamps(tmp_path):
    path = tmp_path / "ns.pcap"
    frame = bytes(60)
    path.write_bytes(struct.pack("<IHHiIII", 0xA1B23C4D, 2, 4, 0, 0, 65535, 1)
                     + struct.pack("<IIII", 1_700_000_000, 123_456_789, 60, 60) + frame)
    with CaptureReader(path) as reader:
        (_n, ts, _lt, data), = list(reader.packets())
    assert ts == pytest.approx(1_700_000_000.123456789) and data == frame


def test_an_empty_file_is_refused(tmp_path):
    path = tmp_path / "empty.pcap"
    path.write_bytes(b"")
    with pytest.raises(CaptureError, match="empty"):
        CaptureReader(path)


@pytest.mark.parametrize("content, words", [
    (b'{"not": "a capture"}\n', "text"),
    (b"\x89PNG\r\n\x1a\n" + bytes(100), "89 50 4e 47"),
])
def test_a_file_that_is_not_a_capture_is_refused(tmp_path, content, words):
    path = tmp_path / "x.pcap"
    path.write_bytes(content)
    with pytest.raises(CaptureError, match="not a pcap or pcapng capture") as info:
        CaptureReader(path)
    assert words in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("fmt", ["pcap", "pcapng"])
def test_a_file_cut_inside_its_header_is_refused(tmp_path, fmt):
    _cap, path = _capture(tmp_path, fmt)
    path.write_bytes(path.read_bytes()[:10])
    with pytest.raises(CaptureError, match="cut short inside its file header"):
        CaptureReader(path)


def test_a_pcap_cut_inside_a_record_is_reported_after_the_last_whole_packet(tmp_path):
    cap, path = _capture(tmp_path, "pcap")
    data = path.read_bytes()
    path.write_bytes(data[:-20])  # the last packet loses 20 bytes
    with CaptureReader(path) as reader:
        got = list(reader.packets())
    assert len(got) == len(cap.packets) - 1
    assert "cut short" in reader.truncated


def test_a_pcap_cut_inside_a_record_header_is_reported(tmp_path):
    cap, path = _capture(tmp_path, "pcap")
    path.write_bytes(path.read_bytes() + b"\x01\x02\x03")
    with CaptureReader(path) as reader:
        assert len(list(reader.packets())) == len(cap.packets)
    assert "3 stray bytes" in reader.truncated


def test_a_pcapng_cut_short_is_known_before_reading(tmp_path):
    _cap, path = _capture(tmp_path, "pcapng")
    path.write_bytes(path.read_bytes()[:-7])
    reader = CaptureReader(path)
    assert reader.truncated is not None and "cut short" in reader.truncated
    reader.close()


def test_a_record_announcing_an_absurd_length_is_corruption(tmp_path):
    path = tmp_path / "bad.pcap"
    path.write_bytes(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1)
                     + struct.pack("<IIII", 1, 0, 0x7FFFFFFF, 60) + bytes(60))
    with CaptureReader(path) as reader, pytest.raises(CaptureError, match="corrupt"):
        list(reader.packets())


def test_a_missing_file_is_one_line(tmp_path):
    with pytest.raises(CaptureError, match="No such file"):
        CaptureReader(tmp_path / "nope.pcap")
