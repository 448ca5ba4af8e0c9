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
(``tests/test_pcap.py`` compares them with scapy's ``Ether()/IP()/TCP()/Raw``) at a
small fraction of the cost, so a 5,000-pose case is not slowed down by its evidence.
"""

from __future__ import annotations

import ipaddress
import logging
import os
import struct
import threading
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from conformance.harness.transcript import ConnectionInfo, Kind, Transcript, WireEvent

__all__ = ["PcapNgFile", "PcapRecorder", "write_transcript", "MAX_SEGMENT", "LINKTYPE_ETHERNET"]

log = logging.getLogger(__name__)

#: Largest TCP payload per synthesised segment: larger sends/recvs are split.
MAX_SEGMENT = 65000
#: Advertised MSS on SYN / SYN-ACK (Linux loopback: MTU 65536 - 40).
_MSS = 65495
_WINDOW = 65535
LINKTYPE_ETHERNET = 1
LINKTYPE_WIRESHARK_UPPER_PDU = 252

# pcapng (little-endian section)
_SHB, _IDB, _EPB = 0x0A0D0D0A, 0x00000001, 0x00000006
_BYTE_ORDER_MAGIC = 0x1A2B3C4D
_OPT_END, _OPT_COMMENT = 0, 1
_SHB_USERAPPL, _IF_NAME, _IF_DESCRIPTION, _IF_TSRESOL = 4, 2, 3, 9
_EPB_HEAD = struct.Struct("<IIIIIII")  # type, total length, if id, ts high, ts low, caplen, len
_U32 = struct.Struct("<I")

# TCP flags
_FIN, _SYN, _RST, _PSH, _ACK = 0x01, 0x02, 0x04, 0x08, 0x10

_ETH_IPV4 = bytes(12) + b"\x08\x00"  # zero MACs, as Linux loopback
_ETH_IPV6 = bytes(12) + b"\x86\xdd"
_IPV4 = struct.Struct("!BBHHHBBH4s4s")
_IPV6 = struct.Struct("!IHBB16s16s")
_TCP = struct.Struct("!HHIIBBHHH")
_UDP = struct.Struct("!HHHH")
_TCP_MSS_OPTION = struct.pack("!BBH", 2, 4, _MSS)
_PROTO_TCP, _PROTO_UDP = 6, 17
_KINDS = frozenset(
    (Kind.CONNECT, Kind.CONNECT_FAILED, Kind.SEND, Kind.RECV, Kind.CLOSE, Kind.ABORT, Kind.PEER_CLOSE, Kind.PEER_RESET)
)
# An unused-by-Linux ephemeral range (Linux uses 32768-60999) for a failed connect
# whose local port was never known.
_SYNTHETIC_PORT_BASE = 61000


def _sum16(data: bytes) -> int:
    """The 16-bit words of ``data`` (even length) summed modulo 0xFFFF (2**16 == 1)."""
    return int.from_bytes(data, "big") % 0xFFFF


def _fold(total: int) -> int:
    """The Internet checksum of words whose sum modulo 0xFFFF is ``total``.

    The words are never all zero here (an IP header, a pseudo-header with a protocol
    number), so a sum divisible by 0xFFFF is the ones'-complement 0xFFFF (-0), whose
    complement is 0x0000, as Linux and scapy write it."""
    total %= 0xFFFF
    return 0xFFFF - total if total else 0x0000


def _payload_sum(data: bytes) -> int:
    return _sum16(data + b"\x00" if len(data) & 1 else data)


def _pad4(data: bytes) -> bytes:
    return data + b"\x00" * (-len(data) % 4)


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + _pad4(value)


def _block(block_type: int, body: bytes) -> bytes:
    total = 12 + len(body)
    return _U32.pack(block_type) + _U32.pack(total) + body + _U32.pack(total)


def _address(host: str, want_v6: bool | None = None) -> tuple[bytes, bool]:
    """Packed address and family; a host name or wildcard becomes loopback."""
    host = host.split("%", 1)[0].strip("[]")
    try:
        addr = ipaddress.ip_address(host)
    except ValueError:
        addr = None
    if addr is not None and not addr.is_unspecified and (want_v6 is None or (addr.version == 6) == want_v6):
        return addr.packed, addr.version == 6
    v6 = want_v6 if want_v6 is not None else ":" in host
    return (ipaddress.IPv6Address("::1") if v6 else ipaddress.IPv4Address("127.0.0.1")).packed, v6


@dataclass
class _Conn:
    info: ConnectionInfo
    v6: bool
    local: bytes
    remote: bytes
    lport: int
    rport: int
    seq: dict[bool, int]  # next sequence number, keyed by "from local"
    ip_id: dict[bool, int] = field(default_factory=lambda: {True: 0, False: 0})
    opened: bool = False  # handshake drawn
    fin: dict[bool, bool] = field(default_factory=lambda: {True: False, False: False})
    reset: bool = False
    notes: list[str] = field(default_factory=list)
    described: bool = False


class PcapNgFile:
    """A minimal pcapng writer: one little-endian section, interfaces added on demand,
    Enhanced Packet Blocks with comments, microsecond time stamps.

    The file is unbuffered: each :meth:`write` is one ``write(2)`` (a whole event's
    packets, or one captured packet), so the file on disk always ends at a block
    boundary unless the process dies inside that one call. A write error is logged and
    kept in :attr:`error`, and the file stops recording: evidence never breaks a case.
    """

    def __init__(self, path: str | os.PathLike[str], *, application: str, comment: str = "") -> None:
        self.path = Path(path)
        self.packets = 0  #: packets written so far
        self.error: OSError | None = None
        self.interfaces = 0
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: BinaryIO | None = open(self.path, "wb", buffering=0)  # noqa: SIM115 - closed in close()
        opts = _option(_SHB_USERAPPL, application.encode())
        if comment:
            opts += _option(_OPT_COMMENT, comment.encode("utf-8", "replace"))
        self.write(_block(_SHB, struct.pack("<IHHq", _BYTE_ORDER_MAGIC, 1, 0, -1) + opts + _option(_OPT_END, b"")))

    @property
    def closed(self) -> bool:
        return self._file is None

    def add_interface(self, linktype: int, name: str, description: str = "") -> int:
        """Write an Interface Description Block; its id for :meth:`epb`."""
        opts = _option(_IF_NAME, name.encode())
        if description:
            opts += _option(_IF_DESCRIPTION, description.encode())
        opts += _option(_IF_TSRESOL, b"\x06") + _option(_OPT_END, b"")
        self.write(_block(_IDB, struct.pack("<HHI", linktype, 0, 0) + opts))
        self.interfaces += 1
        return self.interfaces - 1

    def epb(self, frame: bytes, t: float, comments: list[str] | None = None, ifid: int = 0) -> bytes:
        """One Enhanced Packet Block (not yet written: pass it to :meth:`write`)."""
        us = round(t * 1_000_000)
        opts = b""
        if comments:
            for text in comments:
                opts += _option(_OPT_COMMENT, text.encode("utf-8", "replace"))
            opts += _option(_OPT_END, b"")
        size = len(frame)
        total = 32 + ((size + 3) & ~3) + len(opts)
        self.packets += 1
        return b"".join(
            (
                _EPB_HEAD.pack(_EPB, total, ifid, us >> 32, us & 0xFFFFFFFF, size, size),
                frame,
                b"\x00" * (-size % 4),
                opts,
                _U32.pack(total),
            )
        )

    def write_packet(self, frame: bytes, t: float, comments: list[str] | None = None, ifid: int = 0) -> None:
        self.write(self.epb(frame, t, comments, ifid))

    def write(self, data: bytes) -> None:
        """Write whole blocks (one system call; the file is unbuffered)."""
        if self._file is None or not data:
            return
        try:
            view = memoryview(data)
            while view:  # an unbuffered FileIO may write short
                n = self._file.write(view)
                view = view[n or 0 :]
        except OSError as exc:
            self._fail(exc)

    def close(self) -> None:
        if self._file is not None:
            try:
                self._file.close()
            except OSError as exc:  # pragma: no cover - disk full on close
                self._fail(exc)
            self._file = None

    def _fail(self, exc: OSError) -> None:
        self.error = exc
        log.error("pcapng evidence %s: %s; recording stopped", self.path, exc)
        try:
            if self._file is not None:
                self._file.close()
        except OSError:
            pass
        self._file = None


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
        name = _pad4(b"data-text-lines")  # EXP_PDU_TAG_DISSECTOR_NAME (12), NUL-padded
        tags = struct.pack("!HH", 12, len(name)) + name + struct.pack("!HH", 0, 0)
        return self._epb(tags + text, self._last_t, [self._comment(n) for n in notes], self._notes_ifid)

    # -- connections -------------------------------------------------------------------
    def _conn(self, info: ConnectionInfo) -> _Conn:
        conn = self._conns.get(info.conn)
        if conn is not None:
            return conn
        remote, v6 = _address(info.remote.host)
        if _is_ip(info.local.host) and not _unspecified(info.local.host):
            local, _ = _address(info.local.host, v6)
        else:  # e.g. "0.0.0.0" of a connect that failed: the source was never known
            local = remote if _is_loopback(info.remote.host) else bytes(16 if v6 else 4)
        lport = info.local.port or _SYNTHETIC_PORT_BASE + info.conn % 4500
        seed = f"{self.case_id}/{info.conn}".encode()
        isn_local = zlib.crc32(seed + b"/local")
        isn_remote = zlib.crc32(seed + b"/remote")
        conn = _Conn(info, v6, local, remote, lport, info.remote.port, {True: isn_local, False: isn_remote})
        self._conns[info.conn] = conn
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

    # -- events ------------------------------------------------------------------------
    def _event(self, conn: _Conn, ev: WireEvent) -> None:
        kind = ev.kind
        self._last_t = ev.t
        if kind == Kind.NOTE:
            if ev.note:
                (conn.notes if ev.conn else self._global_notes).append(ev.note)
            return
        transport = conn.info.transport
        if transport == "udp":
            if kind in (Kind.SEND, Kind.RECV):
                out = kind == Kind.SEND
                comments = self._take_comments(conn, ev.note)
                self._write(self._epb(self._udp(conn, out, ev.data), ev.t, comments))
            elif ev.note:
                conn.notes.append(f"{kind}: {ev.note}")
            return
        if transport != "tcp":
            if ev.note:
                conn.notes.append(ev.note)
            return
        t = ev.t
        if kind == Kind.CONNECT_FAILED:
            if not conn.opened and not conn.reset:
                self._write(self._connect_failed(conn, ev))
            elif ev.note:
                conn.notes.append(ev.note)
            return
        # Does this event put anything on the wire? (After a reset nothing does; a
        # zero-byte send, a second close of one side, a repeated connect do not.)
        if conn.reset:
            wire = False
        elif kind in (Kind.SEND, Kind.RECV):
            wire = bool(ev.data)
        elif kind in (Kind.CLOSE, Kind.PEER_CLOSE):
            wire = not conn.fin[kind == Kind.CLOSE]
        elif kind in (Kind.ABORT, Kind.PEER_RESET):
            wire = True
        elif kind == Kind.CONNECT:
            wire = not conn.opened
        else:
            wire = False
        if not wire:  # keep the note for the next packet of this connection
            if ev.note:
                conn.notes.append(ev.note if kind in _KINDS else f"{kind}: {ev.note}")
            return
        packets: list[bytes] = []
        comments = self._take_comments(conn, ev.note)
        if not conn.opened:
            passive = kind == Kind.CONNECT and ev.note.lower().startswith("accepted")
            if kind != Kind.CONNECT:
                comments.insert(0, self._comment("handshake not in the transcript; drawn here"))
            packets += self._handshake(conn, t, comments, passive)
            comments = []
        if kind in (Kind.SEND, Kind.RECV):
            packets += self._data(conn, kind == Kind.SEND, ev.data, t, comments)
        elif kind in (Kind.CLOSE, Kind.PEER_CLOSE):
            packets += self._fin(conn, kind == Kind.CLOSE, t, comments)
        elif kind in (Kind.ABORT, Kind.PEER_RESET):
            packets.append(self._epb(self._tcp(conn, kind == Kind.ABORT, _RST | _ACK), t, comments))
            conn.reset = True
        self._write(b"".join(packets))

    def _handshake(self, conn: _Conn, t: float, comments: list[str], passive: bool) -> list[bytes]:
        client = not passive  # True: we (local) sent the SYN
        syn_seq, synack_seq = conn.seq[client], conn.seq[not client]
        syn = self._tcp(conn, client, _SYN, seq=syn_seq, ack=0, options=_TCP_MSS_OPTION)
        conn.seq[client] = syn_seq + 1
        synack = self._tcp(conn, not client, _SYN | _ACK, seq=synack_seq, ack=syn_seq + 1, options=_TCP_MSS_OPTION)
        conn.seq[not client] = synack_seq + 1
        ack = self._tcp(conn, client, _ACK)
        conn.opened = True
        return [self._epb(syn, t, comments), self._epb(synack, t), self._epb(ack, t)]

    def _connect_failed(self, conn: _Conn, ev: WireEvent) -> bytes:
        comments = self._take_comments(conn, ev.note or "connect failed")
        seq = conn.seq[True]
        syn = self._tcp(conn, True, _SYN, seq=seq, ack=0, options=_TCP_MSS_OPTION)
        out = self._epb(syn, ev.t, comments)
        note = ev.note.lower()
        if "refused" in note or "reset" in note:
            out += self._epb(self._tcp(conn, False, _RST | _ACK, seq=0, ack=seq + 1), ev.t)
        conn.reset = True
        return out

    def _data(self, conn: _Conn, out: bool, data: bytes, t: float, comments: list[str]) -> list[bytes]:
        packets: list[bytes] = []
        step = self.max_segment
        size = len(data)
        for start in range(0, size, step):
            chunk = data[start : start + step]
            last = start + step >= size
            packets.append(self._epb(self._tcp(conn, out, _ACK | (_PSH if last else 0), payload=chunk), t, comments))
            comments = []
            conn.seq[out] = (conn.seq[out] + len(chunk)) & 0xFFFFFFFF
            packets.append(self._epb(self._tcp(conn, not out, _ACK), t))
        return packets

    def _fin(self, conn: _Conn, out: bool, t: float, comments: list[str]) -> list[bytes]:
        fin = self._tcp(conn, out, _FIN | _ACK)
        conn.seq[out] = (conn.seq[out] + 1) & 0xFFFFFFFF
        conn.fin[out] = True
        return [self._epb(fin, t, comments), self._epb(self._tcp(conn, not out, _ACK), t)]

    # -- headers -----------------------------------------------------------------------
    def _ip(self, conn: _Conn, out: bool, proto: int, segment_len: int) -> tuple[bytes, int]:
        """Ethernet + IP header for a segment, and the pseudo-header's checksum sum."""
        src, dst = (conn.local, conn.remote) if out else (conn.remote, conn.local)
        if conn.v6:
            ip = _IPV6.pack(0x60000000, segment_len & 0xFFFF, proto, 64, src, dst)
            pseudo = _sum16(src + dst) + segment_len + proto
            return _ETH_IPV6 + ip, pseudo
        ident = conn.ip_id[out]
        conn.ip_id[out] = (ident + 1) & 0xFFFF
        total = min(20 + segment_len, 0xFFFF)
        head = _IPV4.pack(0x45, 0, total, ident, 0x4000, 64, proto, 0, src, dst)
        csum = _fold(_sum16(head))
        head = head[:10] + csum.to_bytes(2, "big") + head[12:]
        pseudo = _sum16(src + dst) + proto + segment_len
        return _ETH_IPV4 + head, pseudo

    def _tcp(
        self,
        conn: _Conn,
        out: bool,
        flags: int,
        *,
        seq: int | None = None,
        ack: int | None = None,
        options: bytes = b"",
        payload: bytes = b"",
    ) -> bytes:
        if seq is None:
            seq = conn.seq[out]
        if ack is None:
            ack = conn.seq[not out] if flags & _ACK else 0
        sport, dport = (conn.lport, conn.rport) if out else (conn.rport, conn.lport)
        hlen = 20 + len(options)
        head = _TCP.pack(sport, dport, seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, (hlen // 4) << 4, flags, _WINDOW, 0, 0)
        head += options
        eth_ip, pseudo = self._ip(conn, out, _PROTO_TCP, hlen + len(payload))
        csum = _fold(pseudo + _sum16(head) + (_payload_sum(payload) if payload else 0))
        return eth_ip + head[:16] + csum.to_bytes(2, "big") + head[18:] + payload

    def _udp(self, conn: _Conn, out: bool, payload: bytes) -> bytes:
        sport, dport = (conn.lport, conn.rport) if out else (conn.rport, conn.lport)
        length = 8 + len(payload)
        head = _UDP.pack(sport, dport, length & 0xFFFF, 0)
        eth_ip, pseudo = self._ip(conn, out, _PROTO_UDP, length)
        csum = _fold(pseudo + _sum16(head) + _payload_sum(payload)) or 0xFFFF  # RFC 768: 0 means "none"
        return eth_ip + head[:6] + csum.to_bytes(2, "big") + payload


def _ip_or_none(host: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        return ipaddress.ip_address(host.split("%", 1)[0].strip("[]"))
    except ValueError:
        return None


def _is_ip(host: str) -> bool:
    return _ip_or_none(host) is not None


def _unspecified(host: str) -> bool:
    addr = _ip_or_none(host)
    return addr is not None and addr.is_unspecified


def _is_loopback(host: str) -> bool:
    addr = _ip_or_none(host)
    return host == "localhost" if addr is None else addr.is_loopback


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
