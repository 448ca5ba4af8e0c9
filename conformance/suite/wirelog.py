"""A case's transcript as report lines: each chunk on the wire with what it decodes to."""

from __future__ import annotations

from ..harness.transcript import Kind, Transcript
from ..protocol import Frame, Profile, ProtocolError, StreamDecoder, TransferType, decode_datagram
from .verdicts import WireLine

#: Reports show at most this many lines per case (the pcap has everything).
MAX_LINES = 2000
_ARROW = {Kind.SEND: "→", Kind.RECV: "←"}


def _summaries(decoder: StreamDecoder, data: bytes) -> str:
    parts = []
    for event in decoder.feed(data):
        if isinstance(event, Frame):
            parts.append(event.describe())
        else:
            parts.append(f"[{event.clause}] {event.message}")
    if decoder.buffered:
        parts.append(f"({decoder.buffered} bytes of an incomplete frame)")
    return "; ".join(parts)


def wire_lines(transcript: Transcript, profile: Profile, limit: int = MAX_LINES) -> list[WireLine]:
    start = transcript.started or 0.0
    decoders: dict[tuple[int, str], StreamDecoder] = {}
    lines: list[WireLine] = []
    for event in transcript.events:
        if len(lines) >= limit:
            lines.append(WireLine(0.0, 0, "·", "note", "", f"… {len(transcript.events) - limit} more events in the pcap"))
            break
        t_ms = (event.t - start) * 1000
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
            lines.append(WireLine(round(t_ms, 3), event.conn, _ARROW[event.kind], event.kind, event.data.hex(" "), summary))
        else:
            label = f" ({info.label}, {info.transport} {info.local} → {info.remote})" if info and event.kind == Kind.CONNECT else ""
            lines.append(WireLine(round(t_ms, 3), event.conn, "·", event.kind, "", (event.note or "") + label))
    return lines
