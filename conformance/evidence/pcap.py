"""Per-case pcapng evidence, synthesised from the exact socket transcript.

A :class:`PcapRecorder` is a transcript :class:`~conformance.harness.transcript.Listener`:
attach it to a case's :class:`~conformance.harness.transcript.Transcript` and it writes a
pcapng file *as the events arrive*. Every event's packets go to the file in one write
to an unbuffered file, so a run that is interrupted (Ctrl-C, a kill, a crash) leaves a
file that Wireshark and tshark read up to the last complete event.

The packets are what the socket calls imply, on Ethernet (as Linux shows loopback),
IPv4 or IPv6 (an endpoint host containing ``:``), with the addresses and ports the
transcript recorded and the event's own time stamp (to the microsecond):

========================  ====================================================================
event                     packets
========================  ====================================================================
``connect`` (TCP)         SYN, SYN-ACK, ACK (MSS 65495, no window scaling)
``send`` / ``recv``       data segments of at most ``max_segment`` bytes (PSH on the last), each
                          followed by the receiver's pure ACK; seq/ack advance with the bytes
``close`` / ``peer-close``  FIN-ACK from the side that closed, ACK from the other
``abort`` / ``peer-reset``  RST-ACK from the side that reset
``connect-failed``        SYN and the server's RST-ACK when the note says "refused" (or "reset");
                          a lone SYN otherwise (timed out, unreachable)
UDP ``send`` / ``recv``   one datagram each (``connect`` writes nothing)
``note``                  a comment on the next packet of that connection; notes still pending
                          at :meth:`close` go on a marker frame of a second interface
                          ``isight-notes`` (an exported PDU that Wireshark shows as text)
========================  ====================================================================

Every comment starts with the case ID (``"F1-001: liveness probe"``): the first packet of
each connection says which connection it is, and the first packet of an event carries
the pending notes and the event's own note. IP and TCP/UDP checksums are correct. The
initial sequence numbers are derived from the case ID and connection number, so the
same transcript always gives the same file: :func:`write_transcript` (after the fact)
writes byte for byte what live recording wrote.

An event that puts nothing on the wire (a zero-byte send, a close after a reset)
passes its note on to the next packet. ``Transcript.add`` does not call listeners for
transcript-level notes (``conn`` 0); neither does :func:`write_transcript`.

A transcript does not say who opened a TCP connection; the recorder assumes we did
(the suite is the robot, the client). A ``connect`` event whose note starts with
``"accepted"`` is drawn as a passive open (the SYN comes from the remote end).

Packets are built with ``struct`` rather than scapy: the result is the same bytes
(``tests/e2e/test_pcap.py`` compares them with scapy's ``Ether()/IP()/TCP()/Raw``) at a
small fraction of the cost, so a 5,000-pose case is not slowed down by its evidence.

The container is :mod:`.pcapng`; the packets of one connection (addresses, seq/ack,
checksums) are :mod:`.packet_builder`. This module turns transcript events into them.
"""

from __future__ import annotations

import os
import struct
import threading
from dataclasses import dataclass, field
from pathlib import Path

from conformance.harness.transcript import ConnectionInfo, Kind, Transcript, WireEvent

from . import packet_builder
from .packet_builder import MAX_SEGMENT, Flow
from .pcapng import LINKTYPE_ETHERNET, LINKTYPE_WIRESHARK_UPPER_PDU, PcapNgFile, pad4

__all__ = ["PcapNgFile", "PcapRecorder", "write_transcript", "MAX_SEGMENT", "LINKTYPE_ETHERNET"]

_KINDS = frozenset(
    (Kind.CONNECT, Kind.CONNECT_FAILED, Kind.SEND, Kind.RECV, Kind.CLOSE, Kind.ABORT, Kind.PEER_CLOSE, Kind.PEER_RESET)
)


@dataclass
class _Conn:
    """A connection of the transcript: its packets' flow, and the notes waiting for its next packet."""

    flow: Flow
    notes: list[str] = field(default_factory=list)
    described: bool = False

    @property
    def info(self) -> ConnectionInfo:
        return self.flow.info


class PcapRecorder:
    """Write a case's transcript to a pcapng file as it happens (a transcript Listener).

    ``PcapRecorder(path, case_id)``; attach with ``transcript.listeners.append(rec)`` or
    :meth:`attach`. The file exists (section and interface headers) as soon as the
    recorder is constructed. A write error never breaks the case: it is logged, kept in
    :attr:`error`, and recording stops.
    """

    def __init__(self, path: str | os.PathLike[str], case_id: str = "", *, max_segment: int = MAX_SEGMENT) -> None:
        if not 1 <= max_segment <= 65495:
            raise ValueError(f"max_segment must be 1..65495, not {max_segment}")
        self.path = Path(path)
        self.case_id = case_id
        self.max_segment = max_segment
        self._conns: dict[int, _Conn] = {}
        self._global_notes: list[str] = []
        self._notes_ifid: int | None = None
        self._last_t = 0.0
        self._lock = threading.Lock()
        self._out = PcapNgFile(
            self.path,
            application="isight-conformance (packets synthesised from the socket transcript)",
            comment=f"case {case_id}" if case_id else "",
        )
        self._out.add_interface(
            LINKTYPE_ETHERNET, "isight-transcript", "packets synthesised from the case's socket transcript"
        )
        self._epb = self._out.epb
        self._write = self._out.write

    @property
    def packets(self) -> int:
        """Packets written so far."""
        return self._out.packets

    @property
    def error(self) -> OSError | None:
        """The write error that stopped recording, if any."""
        return self._out.error

    @property
    def closed(self) -> bool:
        return self._out.closed

    # -- Listener ----------------------------------------------------------------------
    @classmethod
    def attach(cls, transcript: Transcript, path: str | os.PathLike[str], **kwargs: int) -> PcapRecorder:
        """A recorder for ``transcript`` (its case ID), added to its listeners."""
        recorder = cls(path, transcript.case_id, **kwargs)
        transcript.listeners.append(recorder)
        return recorder

    def on_connection(self, transcript: Transcript, info: ConnectionInfo) -> None:
        with self._lock:
            if not self.case_id and transcript.case_id:
                self.case_id = transcript.case_id
            self._conn(info)

    def on_event(self, transcript: Transcript, info: ConnectionInfo, event: WireEvent) -> None:
        with self._lock:
            if self._out.closed:
                return
            if not self.case_id and transcript.case_id:
                self.case_id = transcript.case_id
            self._event(self._conn(info), event)

    def close(self) -> None:
        """Write notes no packet followed (on a marker frame), close the file. Idempotent."""
        with self._lock:
            if self._out.closed:
                return
            leftover = self._global_notes + [n for c in self._conns.values() for n in c.notes]
            self._global_notes = []
            for c in self._conns.values():
                c.notes = []
            if leftover:
                self._write(self._note_marker(leftover))
            self._out.close()

    def flush(self) -> None:
        """Nothing to do: each event is written at once to an unbuffered file."""

    def __enter__(self) -> PcapRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _comment(self, text: str) -> str:
        return f"{self.case_id}: {text}" if self.case_id else text

    def _note_marker(self, notes: list[str]) -> bytes:
        """One frame on a second interface carrying notes no packet followed: an
        exported PDU for Wireshark's text dissector, the notes also as its comments."""
        if self._notes_ifid is None:  # written now, before the marker's packet block
            self._notes_ifid = self._out.add_interface(
                LINKTYPE_WIRESHARK_UPPER_PDU, "isight-notes", "case notes that no packet followed"
            )
        text = "\n".join(notes).encode("utf-8", "replace")
        name = pad4(b"data-text-lines")  # EXP_PDU_TAG_DISSECTOR_NAME (12), NUL-padded
        tags = struct.pack("!HH", 12, len(name)) + name + struct.pack("!HH", 0, 0)
        return self._epb(tags + text, self._last_t, [self._comment(n) for n in notes], self._notes_ifid)

    # -- connections -------------------------------------------------------------------
    def _conn(self, info: ConnectionInfo) -> _Conn:
        conn = self._conns.get(info.conn)
        if conn is None:
            conn = self._conns[info.conn] = _Conn(packet_builder.new_flow(info, self.case_id))
        return conn

    def _take_comments(self, conn: _Conn, event_note: str = "") -> list[str]:
        texts: list[str] = []
        if not conn.described:
            conn.described = True
            i = conn.info
            label = f" {i.label}" if i.label else ""
            texts.append(f"conn {i.conn} {i.transport}{label} {i.local} -> {i.remote}")
        texts += self._global_notes + conn.notes
        self._global_notes, conn.notes = [], []
        if event_note:
            texts.append(event_note)
        return [self._comment(t) for t in texts]

    def _packets(self, frames: list[bytes], t: float, comments: list[str]) -> list[bytes]:
        """The frames of one step as packet blocks; the comments go on the first."""
        return [self._epb(frame, t, comments if i == 0 else None) for i, frame in enumerate(frames)]

    def _event(self, conn: _Conn, ev: WireEvent) -> None:
        kind = ev.kind
        self._last_t = ev.t
        if kind == Kind.NOTE:
            if ev.note:
                (conn.notes if ev.conn else self._global_notes).append(ev.note)
            return
        flow = conn.flow
        transport = flow.info.transport
        if transport == "udp":
            if kind in (Kind.SEND, Kind.RECV):
                out = kind == Kind.SEND
                comments = self._take_comments(conn, ev.note)
                self._write(self._epb(packet_builder.udp(flow, out, ev.data), ev.t, comments))
            elif ev.note:
                conn.notes.append(f"{kind}: {ev.note}")
            return
        if transport != "tcp":
            if ev.note:
                conn.notes.append(ev.note)
            return
        t = ev.t
        if kind == Kind.CONNECT_FAILED:
            if not flow.opened and not flow.reset:
                comments = self._take_comments(conn, ev.note or "connect failed")
                note = ev.note.lower()
                frames = packet_builder.connect_failed(flow, refused="refused" in note or "reset" in note)
                self._write(b"".join(self._packets(frames, t, comments)))
            elif ev.note:
                conn.notes.append(ev.note)
            return
        if not _on_the_wire(flow, ev):  # keep the note for the next packet of this connection
            if ev.note:
                conn.notes.append(ev.note if kind in _KINDS else f"{kind}: {ev.note}")
            return
        blocks: list[bytes] = []
        comments = self._take_comments(conn, ev.note)
        if not flow.opened:
            passive = kind == Kind.CONNECT and ev.note.lower().startswith("accepted")
            if kind != Kind.CONNECT:
                comments.insert(0, self._comment("handshake not in the transcript; drawn here"))
            blocks += self._packets(packet_builder.handshake(flow, passive), t, comments)
            comments = []
        if kind in (Kind.SEND, Kind.RECV):
            blocks += self._packets(packet_builder.data(flow, kind == Kind.SEND, ev.data, self.max_segment), t, comments)
        elif kind in (Kind.CLOSE, Kind.PEER_CLOSE):
            blocks += self._packets(packet_builder.fin(flow, kind == Kind.CLOSE), t, comments)
        elif kind in (Kind.ABORT, Kind.PEER_RESET):
            blocks.append(self._epb(packet_builder.rst(flow, kind == Kind.ABORT), t, comments))
        self._write(b"".join(blocks))


def _on_the_wire(flow: Flow, ev: WireEvent) -> bool:
    """Does this TCP event put anything on the wire? After a reset nothing does; a zero-byte
    send, a second close of one side, a repeated connect do not."""
    kind = ev.kind
    if flow.reset:
        return False
    if kind in (Kind.SEND, Kind.RECV):
        return bool(ev.data)
    if kind in (Kind.CLOSE, Kind.PEER_CLOSE):
        return not flow.fin[kind == Kind.CLOSE]
    if kind in (Kind.ABORT, Kind.PEER_RESET):
        return True
    return kind == Kind.CONNECT and not flow.opened


def write_transcript(
    transcript: Transcript, path: str | os.PathLike[str], case_id: str | None = None, *, max_segment: int = MAX_SEGMENT
) -> Path:
    """Write a finished (or running) transcript to ``path`` as pcapng, after the fact.

    The output is byte for byte what a :class:`PcapRecorder` attached from the start
    wrote. Like a live recorder, it sees only events of connections the transcript knows.
    """
    recorder = PcapRecorder(path, transcript.case_id if case_id is None else case_id, max_segment=max_segment)
    try:
        for info in transcript.connections.values():
            recorder.on_connection(transcript, info)
        for event in list(transcript.events):
            known = transcript.connections.get(event.conn)
            if known is not None:
                recorder.on_event(transcript, known, event)
    finally:
        recorder.close()
    return recorder.path
