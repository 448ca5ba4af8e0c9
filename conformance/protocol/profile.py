"""The profile: every **[decision]** of PROTOCOL.md as a setting.

A vendor box that read the source document differently is tested by changing the
profile, and the report says which reading was used (:meth:`Profile.describe`).
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import struct
from collections.abc import Callable, Mapping
from typing import Any, Literal

import crcmod.predefined

from .constants import Action


class TcpCheckPolicy(str, enum.Enum):
    """F6: what a TCP *receiver* accepts in the check field (a sender always sends 00 00)."""

    ZERO = "zero"  # only 00 00
    ZERO_OR_CRC = "zero-or-crc"  # 00 00 or the correct CRC (PROTOCOL.md's reading)
    IGNORE = "ignore"  # anything


def crc16_names() -> tuple[str, ...]:
    """Every crcmod predefined algorithm that is 16 bits wide (F7)."""
    table = getattr(crcmod.predefined, "_crc_definitions", ())
    names = [d["name"] for d in table if 1 << 16 <= d["poly"] < 1 << 17]
    return tuple(names) or ("modbus", "xmodem", "kermit", "crc-16", "x-25", "crc-ccitt-false")


@functools.cache
def crc_function(name: str) -> Callable[[bytes], int]:
    """A fast CRC-16 function for a crcmod predefined name (raises ValueError)."""
    if name not in crc16_names():
        raise ValueError(
            f"unknown CRC-16 algorithm {name!r}; choose one of: {', '.join(crc16_names())}"
        )
    return crcmod.predefined.mkPredefinedCrcFun(name)


#: a byte order as ``int.to_bytes`` takes it (F4, F7, B4/E1)
ByteOrder = Literal["big", "little"]

_BYTE_ORDERS: tuple[ByteOrder, ...] = ("big", "little")


@dataclasses.dataclass(frozen=True)
class Profile:
    """Settings for one reading of the protocol. Defaults are PROTOCOL.md's decisions."""

    #: F7: crcmod predefined CRC-16 name for UDP frames.
    crc: str = "modbus"
    #: F7: byte order of the CRC in the check field.
    crc_byte_order: ByteOrder = "big"
    #: B3: index of the first block (the normative text says 0, a diagram shows 1).
    first_index: int = 0
    #: F6: what a TCP receiver accepts in the check field.
    tcp_check: TcpCheckPolicy = TcpCheckPolicy.ZERO_OR_CRC
    #: F4: byte order of multi-byte header fields.
    byte_order: ByteOrder = "big"
    #: B4/E1: byte order of float32 and int32 block values.
    float_byte_order: ByteOrder = "big"
    #: T1: bound on connect and every answer, in milliseconds.
    time_out_ms: int = 5000
    #: E3: bound on the vision result answer (action 0x27), in milliseconds.
    vision_time_out_ms: int = 5000
    #: T2: the robot's stream rate in Hz.
    pose_rate_hz: float = 50.0
    #: E2: where a ProgIdx conflict (409) travels: in the block, or as the error code.
    progidx_conflict: str = "block"
    #: Strict checks SHOULD rules too (B4 non-finite floats); lenient accepts them
    #: and accepts a first block index of 0 or 1.
    strict: bool = True

    def __post_init__(self) -> None:
        crc_function(self.crc)  # validates the name
        for name in ("crc_byte_order", "byte_order", "float_byte_order"):
            if getattr(self, name) not in _BYTE_ORDERS:
                raise ValueError(f"{name} must be 'big' or 'little', not {getattr(self, name)!r}")
        if self.first_index not in (0, 1):
            raise ValueError(f"first_index must be 0 or 1, not {self.first_index!r}")
        object.__setattr__(self, "tcp_check", TcpCheckPolicy(self.tcp_check))
        if self.time_out_ms <= 0 or self.vision_time_out_ms <= 0:
            raise ValueError("time-outs must be positive milliseconds")
        if not 0 < self.pose_rate_hz <= 10_000:
            raise ValueError(f"pose_rate_hz must be in (0, 10000], not {self.pose_rate_hz!r}")
        if self.progidx_conflict not in ("block", "error-code"):
            raise ValueError("progidx_conflict must be 'block' or 'error-code'")

    # -- time bounds, in the unit each caller needs ---------------------------------------
    @property
    def time_out_s(self) -> float:
        """T1: the bound on connect and every answer, in seconds."""
        return self.time_out_ms / 1000

    @property
    def vision_time_out_s(self) -> float:
        """E3: the bound on the vision result answer (action 0x27), in seconds."""
        return self.vision_time_out_ms / 1000

    def answer_bound_s(self, action: int | None) -> float:
        """The bound on the answer to a request of ``action``: E3's for the vision result, T1's otherwise."""
        return self.vision_time_out_s if action == Action.VISION_RESULT else self.time_out_s

    # -- CRC ---------------------------------------------------------------------
    def crc_of(self, data: bytes) -> int:
        """F7: the CRC-16 of ``data`` under this profile's algorithm."""
        return crc_function(self.crc)(data)

    def check_bytes(self, data: bytes) -> bytes:
        """The two check bytes a UDP sender appends to ``data``."""
        return struct.pack((">H" if self.crc_byte_order == "big" else "<H"), self.crc_of(data))

    # -- conversion ----------------------------------------------------------------
    def replace(self, **changes: Any) -> Profile:
        return dataclasses.replace(self, **changes)

    def swapped(self, header: bool = False, floats: bool = False) -> Profile:
        """This profile with the header's and/or the values' byte order the other way round."""
        flip: dict[ByteOrder, ByteOrder] = {"big": "little", "little": "big"}
        return self.replace(byte_order=flip[self.byte_order] if header else self.byte_order,
                            float_byte_order=flip[self.float_byte_order] if floats else self.float_byte_order)

    def to_dict(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["tcp_check"] = self.tcp_check.value
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Profile:
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"unknown profile settings: {', '.join(sorted(unknown))}")
        return cls(**data)

    def differences(self) -> dict[str, Any]:
        """Settings that differ from PROTOCOL.md's defaults."""
        default = DEFAULT_PROFILE.to_dict()
        return {k: v for k, v in self.to_dict().items() if default[k] != v}

    def describe(self) -> str:
        diff = self.differences()
        if not diff:
            return "PROTOCOL.md defaults"
        return ", ".join(f"{k}={v}" for k, v in sorted(diff.items()))


DEFAULT_PROFILE = Profile()
