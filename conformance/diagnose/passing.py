"""The passing request a failing valid one is paired with (isolation, :mod:`.isolate`): the same action and block
count with the values every probe sends, or every value 1.0, or 0.0 (pure: frames built in the run's profile)."""

from __future__ import annotations

import struct

from ..protocol.constants import HEADER_LEN
from .differences import REQUESTS
from .experiments import BLOCK_ACTIONS, Prober, block_request


def standard(p: Prober, frame: bytes) -> bytes | None:
    """The request of ``frame``'s action and block count with the values every probe sends."""
    action, count = frame[5], frame[7]
    if action in BLOCK_ACTIONS:
        return block_request(p, action, count) if count else None
    return p.valid_request(action) if action in REQUESTS else None


def standards(p: Prober, frame: bytes) -> list[bytes]:
    """Passing candidates for a valid block request: the probes' values, then every value 1.0, then 0.0 (a box
    may refuse the probes' negative values too)."""
    first = standard(p, frame)
    if first is None or frame[5] not in BLOCK_ACTIONS:
        return [first] if first is not None else []
    out = [first]
    order = ">f" if p.profile.float_byte_order == "big" else "<f"
    size = BLOCK_ACTIONS[frame[5]]
    for value in (1.0, 0.0):
        other = bytearray(first)
        for i in range(frame[7]):
            for k in range((size - 1) // 4):
                at = HEADER_LEN + i * size + 1 + 4 * k
                other[at:at + 4] = struct.pack(order, value)
        out.append(bytes(other))
    return out
