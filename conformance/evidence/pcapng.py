"""The pcapng container: a section header, interfaces added on demand, Enhanced Packet Blocks with comments.

:class:`PcapNgFile` writes what the transcript recorder (:mod:`.pcap`) synthesises and
what a live capture (:mod:`.live`) sees. One little-endian section, microsecond time
stamps (``if_tsresol`` 6), comments as ``opt_comment`` options. The file is unbuffered
and every write is whole blocks, so an interrupted run leaves a file that Wireshark
and tshark read up to the last complete block.
"""

from __future__ import annotations

import logging
import os
import struct
from pathlib import Path
from typing import BinaryIO

__all__ = ["LINKTYPE_ETHERNET", "LINKTYPE_WIRESHARK_UPPER_PDU", "PcapNgFile", "pad4"]

log = logging.getLogger(__name__)

LINKTYPE_ETHERNET = 1
LINKTYPE_WIRESHARK_UPPER_PDU = 252

# pcapng (little-endian section)
_SHB, _IDB, _EPB = 0x0A0D0D0A, 0x00000001, 0x00000006
_BYTE_ORDER_MAGIC = 0x1A2B3C4D
_OPT_END, _OPT_COMMENT = 0, 1
_SHB_USERAPPL, _IF_NAME, _IF_DESCRIPTION, _IF_TSRESOL = 4, 2, 3, 9
_EPB_HEAD = struct.Struct("<IIIIIII")  # type, total length, if id, ts high, ts low, caplen, len
_U32 = struct.Struct("<I")


def pad4(data: bytes) -> bytes:
    """``data`` NUL-padded to a multiple of four bytes."""
    return data + b"\x00" * (-len(data) % 4)


def _option(code: int, value: bytes) -> bytes:
    return struct.pack("<HH", code, len(value)) + pad4(value)


def _block(block_type: int, body: bytes) -> bytes:
    total = 12 + len(body)
    return _U32.pack(block_type) + _U32.pack(total) + body + _U32.pack(total)


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
