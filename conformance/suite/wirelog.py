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
_ARROW = {Kind.SEND: "→", Kind.RECV: "←"}


def _summaries(decoder: StreamDecoder, data: bytes) -> str:
    parts = []
    decoder.receive_data(data)
    count = 0
    for event in decoder.events():  # a flood of garbage decodes to thousands: name a few, count the rest
        count += 1
        if count > MAX_EVENTS:
            continue
        if isinstance(event, Frame):
            parts.append(event.describe())
        else:
            parts.append(f"[{event.clause}] {event.message}")
    if count > MAX_EVENTS:
        parts.append(f"… and {count - MAX_EVENTS} more")
    if decoder.buffered:
        parts.append(f"({decoder.buffered} bytes of an incomplete frame)")
    return "; ".join(parts)


def _hex(data: bytes) -> str:
    return data[:MAX_HEX_BYTES].hex(" ")


def wire_lines(transcript: Transcript, profile: Profile, limit: int = MAX_LINES, tail: int = TAIL_LINES) -> list[WireLine]:
    """The first ``limit`` and the last ``tail`` events of a case as report lines (a note between them
    says how many are left out); every chunk is still decoded, so the tail's summaries stay in step."""
    start = transcript.started or 0.0
    decoders: dict[tuple[int, str], StreamDecoder] = {}
    head: list[WireLine] = []
    last: deque[WireLine] = deque(maxlen=tail)
    total = 0
    for event in transcript.events:
        total += 1
        line = _line(event, transcript, profile, decoders, start)
        if len(head) < limit:
            head.append(line)
        else:
            last.append(line)
    left_out = total - len(head) - len(last)
    if left_out:
        head.append(WireLine(0.0, 0, "·", "note", "", f"… {left_out} more events (not shown; see the pcap)"))
    return head + list(last)


def _line(event: WireEvent, transcript: Transcript, profile: Profile, decoders: dict[tuple[int, str], StreamDecoder],
          start: float) -> WireLine:
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
            summary = _summaries(decoders[key], event.data)
        if event.note:
            summary = f"{event.note}: {summary}" if summary else event.note
        if len(event.data) > MAX_HEX_BYTES:
            summary += f" [{len(event.data)} bytes: the first {MAX_HEX_BYTES} shown]"
        return WireLine(t_ms, event.conn, _ARROW[event.kind], event.kind, _hex(event.data), summary)
    label = f" ({info.label}, {info.transport} {info.local} → {info.remote})" if info and event.kind == Kind.CONNECT else ""
    return WireLine(t_ms, event.conn, "·", event.kind, "", (event.note or "") + label)
