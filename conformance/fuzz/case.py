"""One fuzz case: the bytes to send, how to send them, and what the box may do with them (the oracle's expectations)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..protocol import ByteOrder, Transport
from .oracle import Expectation


@dataclass(frozen=True)
class FuzzCase:
    """One fuzz example: bytes to send to the box, and what the box may do with them."""

    kind: str  # the strategy, e.g. "F1-start-word"
    clause: str  # the clause the strategy means to break ("" for a valid request)
    data: bytes
    note: str
    transport: Transport = Transport.TCP
    eof: bool = False  # TCP: end the stream after the bytes (a truncated frame): no probe
    filler: bytes = b""  # zero bytes completing a frame the data leaves open (sent after it)
    expects: tuple[Expectation, ...] = field(default=(), compare=False)
    splits: tuple[int, ...] = ()  # R3: the wire is written in pieces cut at these offsets, ``gap_s`` apart
    gap_s: float = 0.0

    @property
    def wire(self) -> bytes:
        """What goes on the wire (before the probe)."""
        return self.data + self.filler

    @property
    def valid(self) -> bool:
        """Every event is a well-formed request the box MUST answer."""
        return bool(self.expects) and all(e.valid for e in self.expects)

    @property
    def actions(self) -> frozenset[int]:
        """Header actions of the events (the probe must answer with another one)."""
        return frozenset(e.action for e in self.expects if e.action is not None)

    @property
    def first_clause(self) -> str:
        """The first clause the reference decoder reports (else the strategy's)."""
        return next((e.clause for e in self.expects if e.clause and not e.valid), self.clause)

    def describe(self) -> str:
        tail = f" +{len(self.filler)} filler" if self.filler else ""
        how = " then end of stream" if self.eof else ""
        if self.splits:
            how += f", written in pieces cut at {list(self.splits)} {self.gap_s * 1000:g} ms apart"
        return f"{self.kind}: {self.note} [{len(self.data)} bytes{tail}{how}]"


def _finite(raw: bytes, order: ByteOrder) -> bytes:
    """float32 words with any all-ones exponent (NaN/inf) turned into a finite value."""
    out = bytearray(raw)
    for i in range(0, len(out) - 3, 4):
        bits = int.from_bytes(out[i : i + 4], order)
        if bits & 0x7F800000 == 0x7F800000:
            out[i : i + 4] = (bits ^ 0x40000000).to_bytes(4, order)
    return bytes(out)


__all__ = ["FuzzCase"]
