"""Codec throughput on pose frames, side by side with a hand-written ``struct`` baseline.

Run on demand: ``python benchmarks/bench_codec.py [--seconds S]``. Prints frames/s for
encode and decode (one pose per frame, the stream's frame, and 10 poses per frame),
for the codec and for a baseline that does the same job by hand: pack/unpack with
precompiled structs, the same header checks (start word, version, transfer type,
action, block type, length, count, check) and index/finiteness checks per block.
"""

from __future__ import annotations

import argparse
import math
import struct
import sys
import timeit
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from conformance.protocol import Action, StreamDecoder, TransferType, Transport, codec_for, pose_blocks, request  # noqa: E402

_H = struct.Struct(">HHBBBBHH")
_P = struct.Struct(">B6f")


def baseline_encode(action: int, poses: list[tuple[float, ...]], error_code: int = 0) -> bytes:
    head = _H.pack(0xFEFE, 1, 0x01, action, 0x01, len(poses), 25, error_code)
    return head + b"".join([_P.pack(i, *p) for i, p in enumerate(poses)]) + b"\x00\x00"


def baseline_decode(data: bytes) -> tuple[int, int, int, list[tuple[float, ...]]]:
    if len(data) < 14:
        raise ValueError("short frame")
    start, version, tt, action, bt, count, blen, error = _H.unpack_from(data)
    if (
        start != 0xFEFE or version != 1 or tt != 0x01 or action not in (0x23, 0x24) or bt != 0x01
        or blen != 25 or not count or len(data) != 14 + count * blen or data[-2:] != b"\x00\x00"
    ):
        raise ValueError("bad header")
    poses = []
    for i in range(count):
        rec = _P.unpack_from(data, 12 + 25 * i)
        if rec[0] != i or not math.isfinite(sum(rec)):
            raise ValueError("bad block")
        poses.append(rec)
    return tt, action, error, poses


def rate(func, seconds: float) -> float:
    """Frames per second: best of 5 runs, each about seconds/5 long."""
    number = max(1, int(timeit.timeit(func, number=2000) and 2000 / timeit.timeit(func, number=2000) * seconds / 5))
    best = min(timeit.repeat(func, number=number, repeat=5))
    return number / best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="total time per measurement (default 5)")
    args = parser.parse_args()
    codec = codec_for()
    rows = []
    for n in (1, 10):
        poses = [tuple(float(i * 6 + k) / 7 for k in range(6)) for i in range(n)]
        frame = request(Action.POSE, pose_blocks(poses))
        data = codec.encode(frame)
        assert data == baseline_encode(0x23, poses), "the baseline must produce the same bytes"
        assert [b.pose for b in codec.parse(data).blocks] == [p[1:] for p in baseline_decode(data)[3]]
        rows.append((f"encode {n} pose", rate(lambda f=frame: codec.encode(f), args.seconds),
                     rate(lambda p=poses: baseline_encode(0x23, p), args.seconds)))
        rows.append((f"decode {n} pose", rate(lambda d=data: codec.parse(d, Transport.TCP, TransferType.ROBOT_TO_BOX), args.seconds),
                     rate(lambda d=data: baseline_decode(d), args.seconds)))
    stream = codec.encode(request(Action.POSE, pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)]))) * 1000

    def stream_decode() -> None:
        events = StreamDecoder().feed(stream)
        assert len(events) == 1000

    stream_rate = rate(stream_decode, args.seconds) * 1000
    print(f"{'measure':<18}{'codec frames/s':>16}{'struct frames/s':>18}{'ratio':>8}")
    for name, ours, base in rows:
        print(f"{name:<18}{ours:>16,.0f}{base:>18,.0f}{base / ours:>7.2f}x")
    print(f"{'stream decode 1':<18}{stream_rate:>16,.0f}{'':>18}{'':>8}  (StreamDecoder, 1000 coalesced frames)")
    print(f"python {sys.version.split()[0]}")


if __name__ == "__main__":
    main()
