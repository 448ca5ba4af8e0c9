"""A case's transcript as report lines: each chunk on the wire with what it decodes to."""

from __future__ import annotations

from collections import deque

from ..harness.transcript import Kind, Transcript, WireEvent
from ..model.verdicts import WireLine
from ..protocol import Frame, Profile, ProtocolError, StreamDecoder, TransferType, decode_datagram

#: Reports keep the first MAX_LINES lines of a case and its last TAIL_LINES (the pcap has everything).
MAX_LINES = 300
TAIL_LINES = 100
#: ... and at most this many bytes of one chunk's hex, and this many decoded events of it.
MAX_HEX_BYTES = 256
MAX_EVENTS = 8
#: ... and decode at most this many events of one case: a box that floods sends megabytes, millions of
#: headers, and decoding them all for lines nobody reads cost a run a minute of CPU
MAX_DECODED = 1_000
NOT_DECODED = f"not decoded: the case's first {MAX_DECODED} events are; the pcap has every byte"
_ARROW = {Kind.SEND: "→", Kind.RECV: "←"}


class _Budget:
    """The events a case's wire log may still decode (:data:`MAX_DECODED`)."""

    def __init__(self) -> None:
        self.left = MAX_DECODED


def _summaries(decoder: StreamDecoder, data: bytes, budget: _Budget) -> str:
    if budget.left <= 0:
        return f"({NOT_DECODED})"
    parts = []
    decoder.receive_data(data)
    count = 0
    for event in decoder.events():  # a flood of garbage decodes to thousands: name a few, count the rest
        count += 1
        budget.left -= 1
        if count <= MAX_EVENTS:
            parts.append(event.describe() if isinstance(event, Frame) else f"[{event.clause}] {event.message}")
        if budget.left <= 0:
            break
    if count > MAX_EVENTS:
        parts.append(f"… and {count - MAX_EVENTS} more")
    if budget.left <= 0:
        parts.append(f"(the rest {NOT_DECODED})")
    elif decoder.buffered:
        parts.append(f"({decoder.buffered} bytes of an incomplete frame)")
    return "; ".join(parts)


def _hex(data: bytes) -> str:
    return data[:MAX_HEX_BYTES].hex(" ")


def wire_lines(transcript: Transcript, profile: Profile, limit: int = MAX_LINES, tail: int = TAIL_LINES) -> list[WireLine]:
    """The first ``limit`` and the last ``tail`` events of a case as report lines (a note between them
    says how many are left out); every chunk is still decoded, so the tail's summaries stay in step, up to
    :data:`MAX_DECODED` events of the case (then the lines say so)."""
    start = transcript.started or 0.0
    decoders: dict[tuple[int, str], StreamDecoder] = {}
    budget = _Budget()
    head: list[WireLine] = []
    last: deque[WireLine] = deque(maxlen=tail)
    total = 0
    for event in transcript.events:
        total += 1
        line = _line(event, transcript, profile, decoders, start, budget)
        if len(head) < limit:
            head.append(line)
        else:
            last.append(line)
    left_out = total - len(head) - len(last)
    if left_out:
        head.append(WireLine(0.0, 0, "·", "note", "", f"… {left_out} more events (not shown; see the pcap)"))
    return head + list(last)


def _line(event: WireEvent, transcript: Transcript, profile: Profile, decoders: dict[tuple[int, str], StreamDecoder],
          start: float, budget: _Budget) -> WireLine:
    t_ms = round((event.t - start) * 1000, 3)
    info = transcript.connections.get(event.conn)
    if event.kind in _ARROW and info is not None:
        expect = TransferType.ROBOT_TO_BOX if event.kind == Kind.SEND else TransferType.BOX_TO_ROBOT
        if info.transport == "udp":
            try:
                summary = decode_datagram(event.data, profile, expect).describe()
            except ProtocolError as exc:
                summary = f"[{exc.clause}] {exc.message}"
        else:
            key = (event.conn, event.kind)
            if key not in decoders:
                decoders[key] = StreamDecoder(profile, expect)
            summary = _summaries(decoders[key], event.data, budget)
        if event.note:
            summary = f"{event.note}: {summary}" if summary else event.note
        if len(event.data) > MAX_HEX_BYTES:
            summary += f" [{len(event.data)} bytes: the first {MAX_HEX_BYTES} shown]"
        return WireLine(t_ms, event.conn, _ARROW[event.kind], event.kind, _hex(event.data), summary)
    label = f" ({info.label}, {info.transport} {info.local} → {info.remote})" if info and event.kind == Kind.CONNECT else ""
    return WireLine(t_ms, event.conn, "·", event.kind, "", (event.note or "") + label)
