"""What a box can do in answer to a request, as values: an answer, bytes that do not parse, silence until the
deadline, a close or a reset (:data:`Outcome`). :mod:`.client` returns them; nothing a box does raises."""

from __future__ import annotations

from dataclasses import dataclass

from ..protocol import Frame, ProtocolError

#: descriptions quote at most this many bytes of what the box sent
SHOWN_BYTES = 64


@dataclass(frozen=True)
class Answer:
    """A well-formed answer frame."""

    frame: Frame
    latency_s: float
    raw: bytes

    def describe(self) -> str:
        return f"answered {self.frame.describe()}"


@dataclass(frozen=True)
class Malformed:
    """Bytes from the box that are not a conforming answer."""

    error: ProtocolError
    latency_s: float

    @property
    def raw(self) -> bytes:
        return self.error.raw

    def describe(self) -> str:
        raw = self.error.raw
        shown = raw[:SHOWN_BYTES].hex(" ") + (f" … ({len(raw)} bytes)" if len(raw) > SHOWN_BYTES else "")
        return f"sent a malformed answer: {self.error} ({shown})"


@dataclass(frozen=True)
class Silence:
    """Nothing arrived before the deadline (``skipped``: nothing came for these bytes, but the
    box went on to answer what followed them)."""

    waited_s: float
    skipped: bool = False
    raw = b""  # nothing arrived

    def describe(self) -> str:
        if self.skipped:
            return "did not answer them (it went on to answer the request that followed)"
        return f"stayed silent for {self.waited_s * 1000:.0f} ms"


@dataclass(frozen=True)
class Closed:
    """The box closed (FIN) or reset (RST) the connection, or flooded it and the suite
    stopped reading (``flood``: how many bytes had come)."""

    reset: bool
    latency_s: float
    flood: int = 0
    raw = b""  # no bytes, a FIN or RST

    def describe(self) -> str:
        if self.flood:
            return (f"kept sending ({self.flood} bytes without a pause for an answer to be judged); the suite stopped "
                    "reading and reset the connection (R5)")
        return "reset the connection" if self.reset else "closed the connection"


Outcome = Answer | Malformed | Silence | Closed
