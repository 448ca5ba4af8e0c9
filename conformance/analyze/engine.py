"""One analysis: the capture streams through decoding, reassembly, framing and judgement.

:func:`analyze` reads the file once, packet by packet, and returns an :class:`Analysis`
with the context (findings, figures, capture facts). Nothing of the capture is kept
beyond what the judgement bounds (see :mod:`.findings`): memory does not grow with the
capture's size. ``progress(bytes_read)`` is called every few thousand packets.
"""

from __future__ import annotations

import os
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .analysis_context import AnalyzeConfig, Context
from .capture import CaptureError, CaptureReader
from .capture_packets import TCP, PacketDecoder
from .conversations import Conversations
from .findings import Findings
from .sessions import SessionTracker

__all__ = ["Analysis", "CaptureError", "Feed", "analyze"]

PROGRESS_EVERY = 1 << 14
_TCP_FIELDS = struct.Struct("!IIBB").unpack_from  # seq, ack, data offset, flags (at TCP offset 4)


@dataclass
class Analysis:
    ctx: Context
    path: Path
    format: str
    size: int
    frames: int
    seconds: float  # wall-clock time of the analysis

    @property
    def found(self) -> bool:
        """Any iSight conversation in the capture."""
        s = self.ctx.stats
        return bool(s.tcp_connections or s.udp_conversations)


def _refuse_a_cut_file(reader: CaptureReader, config: AnalyzeConfig) -> None:
    if reader.truncated and not config.accept_truncated:
        raise CaptureError(f"{reader.path}: cut short: {reader.truncated} (--accept-truncated judges the "
                           "frames before the cut)")


class Feed:
    """The engine fed one packet at a time, for traffic that is not in a file (the live
    ``monitor``): the same context, conversations and session judgement :func:`analyze` uses.
    ``findings`` replaces the context's (a subclass that watches what is filed)."""

    def __init__(self, config: AnalyzeConfig, source: Path | None = None, findings: Findings | None = None) -> None:
        self.ctx = Context(config, source)
        if findings is not None:
            self.ctx.findings = findings
        self.decoder = PacketDecoder()
        self.sessions = SessionTracker(self.ctx)
        self.conversations = Conversations(self.ctx, self.sessions)

    def packet(self, linktype: int, data: bytes, no: int, ts: float) -> None:
        """One captured frame, decoded as :func:`analyze` decodes a file's."""
        segment = self.decoder.decode(linktype, data)
        if segment is None:
            return
        proto, key, seq, ack, flags, payload, missing = segment
        self.ctx.now, self.ctx.frame = ts, no
        if proto == TCP:
            self.conversations.tcp_packet(key, seq, ack, flags, payload, missing, no, ts)
        else:
            self.conversations.udp_packet(key, payload, missing, no, ts)

    def finish(self, ts: float, no: int) -> None:
        """The traffic ends: every connection still open is judged as open at the end."""
        self.ctx.now, self.ctx.frame = ts, no
        self.conversations.finish(ts, no)
        self.ctx.stats.skipped = dict(self.decoder.skipped)


def analyze(path: str | os.PathLike[str], config: AnalyzeConfig | None = None,
            progress: Callable[[int, int], None] | None = None) -> Analysis:
    """Judge the capture at ``path``; raises :class:`CaptureError` (one line) for a bad file,
    or a file cut short unless ``config.accept_truncated``."""
    config = config or AnalyzeConfig()
    started = time.perf_counter()
    reader = CaptureReader(path)
    feed = Feed(config, Path(path))
    ctx = feed.ctx
    stats = ctx.stats
    try:
        _refuse_a_cut_file(reader, config)
        packet = feed.packet
        conversations = feed.conversations
        settle = conversations.settle
        known = conversations.tcp.get
        no, ts = 0, 0.0
        for no, ts, linktype, data in reader.packets():
            if not no % PROGRESS_EVERY:
                if progress is not None:
                    progress(reader.position, reader.size)
                ctx.now, ctx.frame = ts, no
            # the short path: Ethernet, IPv4 without options or fragments, TCP, a connection already followed
            if (linktype == 1 and data[12] == 8 and data[13] == 0 and data[14] == 0x45 and data[23] == 6
                    and not data[20] & 0x3F and not data[21]):
                entry = known(data[26:38])
                end = 14 + ((data[16] << 8) | data[17])
                if entry is not None and end <= len(data):
                    seq, ack, off, flags = _TCP_FIELDS(data, 38)
                    result = entry[0](entry[1], seq, ack, flags & 0x3F, data[34 + ((off >> 4) << 2) : end], 0, no, ts)
                    if result is not None:
                        ctx.now, ctx.frame = ts, no
                        settle(entry[2], result, data[26:38], seq, ack, flags & 0x3F,
                               data[34 + ((off >> 4) << 2) : end], 0, no, ts)
                    continue
            packet(linktype, data, no, ts)
        stats.first_ts = reader.first_ts
        _refuse_a_cut_file(reader, config)
        stats.truncated = reader.truncated
        stats.frames = reader.frames
        stats.last_ts = ts if reader.frames else None
        feed.finish(ts, no)
        if progress is not None:
            progress(reader.size, reader.size)
    finally:
        reader.close()
    return Analysis(ctx, Path(path), reader.format, reader.size, reader.frames, time.perf_counter() - started)
