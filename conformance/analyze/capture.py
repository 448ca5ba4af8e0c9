"""Reading a capture file as a stream of link-layer frames: pcap and pcapng.

scapy's raw readers do the file format (``RawPcapReader``, ``RawPcapNgReader``; both
read gzip-compressed files too); this module adds what a judgement needs from them:

* one clear :class:`CaptureError` line for a file that is empty, is not a capture, or
  is cut short (the caller turns it into exit status 2);
* Wireshark's frame numbers (``frame.number``: every packet record, from 1), so a
  finding can name the frame a reader jumps to;
* speed: packets are read with ``_read_packet`` (the call scapy's own ``read_packet``
  points to for raw readers), and the pcapng Enhanced Packet Block, nearly every packet
  of a pcapng file, is read without decoding its options (comments, flags), which the
  judgement never uses. Nothing is kept: the file streams through.

A file cut inside a packet record is noticed at the end (pcap: the records' lengths do
not add up to the file size; pcapng: the last block's trailing length does not match
its leading one, checked before reading). :attr:`CaptureReader.truncated` then says
where, and reading stops at the last whole packet.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from scapy.error import Scapy_Exception
from scapy.utils import RawPcapNgReader, RawPcapReader

__all__ = ["CaptureError", "CaptureReader", "PCAP_MAGICS", "PCAPNG_MAGIC"]

PCAP_MAGICS = (b"\xa1\xb2\xc3\xd4", b"\xd4\xc3\xb2\xa1", b"\xa1\xb2\x3c\x4d", b"\x4d\x3c\xb2\xa1")
PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"
GZIP_MAGIC = b"\x1f\x8b"
#: Largest packet a record may carry; a record announcing more is corruption.
MAX_CAPLEN = 1 << 18
_READ_SIZE = MAX_CAPLEN


class CaptureError(Exception):
    """The file cannot be read as a capture (one line, for exit status 2)."""


class _PcapReader(RawPcapReader):
    """scapy's pcap reader, returning a plain tuple ``(data, (sec, frac, wirelen, caplen))``."""

    def __init__(self, filename: str, fdesc: Any = None, magic: Any = None) -> None:
        super().__init__(filename, fdesc, magic)
        self._record = struct.Struct(self.endian + "IIII").unpack

    def _read_packet(self, size: int = _READ_SIZE) -> Any:
        f = self.f
        hdr = f.read(16)
        if len(hdr) < 16:
            raise EOFError
        sec, frac, caplen, wirelen = self._record(hdr)
        if caplen > MAX_CAPLEN:
            return b"", (sec, frac, wirelen, caplen)
        return f.read(caplen), (sec, frac, wirelen, caplen)


class _NgReader(RawPcapNgReader):
    """scapy's pcapng reader, reading an Enhanced Packet Block (nearly every block of a
    capture) in one call without decoding its options, as a plain tuple ``(data,
    (linktype, tsresol, tshigh, tslow, caplen))``; every other block goes to scapy."""

    def _read_block(self, size: int = _READ_SIZE) -> Any:
        f = self.f
        head = f.read(8)
        if len(head) < 8:
            raise EOFError
        unpack = _NG_HEAD.get(self.endian)
        if unpack is None:  # before the first Section Header Block
            f.seek(-8, 1)
            return super()._read_block(size)
        blocktype, blocklen = unpack(head)
        if blocktype != 6 or blocklen < 32 or blocklen & 3:
            f.seek(-8, 1)
            return super()._read_block(size)
        rest = f.read(blocklen - 8)
        if len(rest) != blocklen - 8 or rest[-4:] != head[4:]:
            raise EOFError
        # the Enhanced Packet Block: interface, time stamp, captured length; options skipped
        intid, tshigh, tslow, caplen = _NG_EPB[self.endian](rest)
        interfaces = self.interfaces
        if intid >= len(interfaces) or caplen > blocklen - 32:
            return None  # scapy skips a block naming no interface too (after a warning)
        iface = interfaces[intid]
        return rest[20 : 20 + caplen], (iface[0], iface[2]["tsresol"], tshigh, tslow, caplen)


_NG_HEAD = {"<": struct.Struct("<II").unpack, ">": struct.Struct(">II").unpack}
_NG_EPB = {"<": struct.Struct("<4I").unpack_from, ">": struct.Struct(">4I").unpack_from}


def _describe_start(head: bytes) -> str:
    if not head:
        return "it is empty"
    if head[:1] in (b"{", b"[") or all(32 <= b < 127 or b in (9, 10, 13) for b in head[:16]):
        return f"it starts with text {head[:16].decode('ascii', 'replace')!r}"
    return f"it starts with bytes {head[:8].hex(' ')}"


class CaptureReader:
    """Open ``path`` (pcap or pcapng, optionally gzip-compressed) or raise CaptureError.

    Iterate :meth:`packets` for ``(frame number, time stamp in s, link type, bytes)``.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        try:
            st = os.stat(self.path)
        except OSError as exc:
            raise CaptureError(f"{self.path}: {exc.strerror or exc}") from None
        if not os.path.isfile(self.path):
            raise CaptureError(f"{self.path}: not a file")
        self.size = st.st_size
        if self.size == 0:
            raise CaptureError(f"{self.path}: the file is empty (0 bytes): not a capture")
        try:
            with open(self.path, "rb") as fh:
                head = fh.read(64)
        except OSError as exc:
            raise CaptureError(f"{self.path}: {exc.strerror or exc}") from None
        self.compressed = head[:2] == GZIP_MAGIC
        magic = head[:4]
        if not self.compressed and magic not in PCAP_MAGICS and magic != PCAPNG_MAGIC:
            raise CaptureError(f"{self.path}: not a pcap or pcapng capture ({_describe_start(head)})")
        if not self.compressed and len(head) < (24 if magic in PCAP_MAGICS else 28):
            raise CaptureError(f"{self.path}: cut short inside its file header ({self.size} bytes): not a whole capture")
        #: None, or where the file is cut short (set before reading for pcapng, at the end for pcap)
        self.truncated: str | None = None
        if magic == PCAPNG_MAGIC and not self.compressed:
            self.truncated = self._pcapng_tail("<" if head[8:12] == b"\x4d\x3c\x2b\x1a" else ">")
        self._reader = self._open(magic)
        self.format = "pcapng" if isinstance(self._reader, RawPcapNgReader) else "pcap"
        self.frames = 0  #: packet records read so far
        self.first_ts: float | None = None  #: time stamp of the first packet

    def _open(self, magic: bytes) -> Any:
        cls = _PcapReader if magic in PCAP_MAGICS else _NgReader
        try:
            if self.compressed:
                reader = RawPcapReader(str(self.path))  # the metaclass falls back to pcapng
                lean = _NgReader if isinstance(reader, RawPcapNgReader) else _PcapReader
                reader.close()
                return lean(str(self.path))
            return cls(str(self.path))
        except Scapy_Exception as exc:
            text = str(exc)
            if "too short" in text or "malformed" in text.lower():
                raise CaptureError(f"{self.path}: cut short inside its file header: not a whole capture") from None
            raise CaptureError(f"{self.path}: not a readable capture ({text})") from None
        except (OSError, EOFError) as exc:
            raise CaptureError(f"{self.path}: not a readable capture ({exc})") from None

    def _pcapng_tail(self, order: str) -> str | None:
        """The last block's trailing length must equal its leading length."""
        try:
            with open(self.path, "rb") as fh:
                fh.seek(self.size - 4)
                (total,) = struct.unpack(order + "I", fh.read(4))
                if 12 <= total <= self.size and total % 4 == 0:
                    fh.seek(self.size - total + 4)
                    (lead,) = struct.unpack(order + "I", fh.read(4))
                    if lead == total:
                        return None
        except (OSError, struct.error):
            pass
        return f"its last block does not end where its length says (a file of {self.size} bytes cut short)"

    @property
    def position(self) -> int:
        """Bytes of the file read so far (of the compressed file for .gz: an estimate)."""
        f = self._reader.f
        try:
            raw = getattr(f, "fileobj", None)
            return int((raw or f).tell())
        except (OSError, ValueError, AttributeError):
            return 0

    def packets(self) -> Iterator[tuple[int, float, int, bytes]]:
        """Every packet: (frame number from 1, time stamp in seconds, link type, captured bytes)."""
        reader = self._reader
        read = reader._read_packet
        number = 0
        try:
            if self.format == "pcap":
                linktype = reader.linktype
                scale = 1e-9 if reader.nano else 1e-6
                expected = 24
                while True:
                    try:
                        data, (sec, frac, _wirelen, caplen) = read(_READ_SIZE)
                    except EOFError:
                        break
                    if caplen > MAX_CAPLEN:
                        raise CaptureError(f"{self.path}: record of frame {number + 1} at byte {expected} announces "
                                           f"{caplen} bytes: the file is corrupt")
                    expected += 16 + caplen
                    number += 1
                    if len(data) < caplen:
                        self.truncated = f"frame {number} is cut short ({len(data)} of {caplen} bytes)"
                        break
                    if number == 1:
                        self.first_ts = sec + frac * scale
                    yield number, sec + frac * scale, linktype, data
                if self.truncated is None and not self.compressed and expected != self.size:
                    self.truncated = (f"{self.size - expected} stray bytes after frame {number}: the file is cut "
                                      "inside a record header")
            else:
                while True:
                    try:
                        data, meta = read(_READ_SIZE)
                    except EOFError:
                        break
                    number += 1
                    if type(meta) is tuple:
                        linktype, tsresol, high, low, _caplen = meta
                    else:  # a Simple or obsolete Packet Block: scapy's metadata
                        linktype, tsresol, high, low = meta.linktype, meta.tsresol, meta.tshigh, meta.tslow
                    ts = ((high << 32) | low) / tsresol if high is not None else 0.0
                    if number == 1:
                        self.first_ts = ts
                    yield number, ts, linktype, data
                if self.truncated is None and not self.compressed and self.position < self.size:
                    self.truncated = f"unreadable block at byte {self.position} after frame {number}"
        except (OSError, Scapy_Exception) as exc:
            raise CaptureError(f"{self.path}: read error after frame {number}: {exc}") from None
        finally:
            self.frames = number

    def close(self) -> None:
        try:
            self._reader.close()
        except OSError:
            pass

    def __enter__(self) -> CaptureReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

