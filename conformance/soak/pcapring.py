"""A ring of pcaps over a soak: every window's packets in ``pcaps/window-NNNNN.pcapng``, the newest
``keep`` windows kept, and every window that holds a finding (a failed session, a missing or late
answer) kept for good.

The packets are the kernel's (:mod:`.sniff`: FIN, RST, retransmissions; a vanished robot's silence
is there too), captured without a gap: at a window's end the sniffer switches files. Capturing needs
root or CAP_NET_RAW; without it the soak goes on without pcaps and soak.json says why.
"""

from __future__ import annotations

import contextlib
from collections import deque
from pathlib import Path
from typing import Any

from .sniff import Sniffer, SniffError
from .windows import WindowRow


class PcapRing:
    def __init__(self, directory: Path, port: int, keep: int, interface: str = "lo") -> None:
        self.directory = directory
        self.keep = keep
        self.recent: deque[Path] = deque()
        self.pinned: list[Path] = []
        self.deleted = 0
        self.error: str | None = None
        self.sniffer: Sniffer | None = None
        self._path: Path | None = None
        try:
            self.sniffer = Sniffer(port, interface)
        except SniffError as exc:
            self.error = str(exc)

    def start(self, index: int) -> None:
        if self.sniffer is None:
            return
        self.directory.mkdir(parents=True, exist_ok=True)
        self._path = self.directory / f"window-{index:05d}.pcapng"
        self.sniffer.switch(self._path, f"isight-conformance soak: window {index}")

    def rotate(self, row: WindowRow) -> None:
        """The window ``row`` closed: keep or drop its file; the next window's file starts now."""
        if self.sniffer is None:
            return
        path = self._path
        self.start(row.index + 1)
        if path is not None:
            self._file(path, row)

    def _file(self, path: Path, row: WindowRow | None) -> None:
        if row is not None and row.has_finding:
            self.pinned.append(path)
            return
        self.recent.append(path)
        while len(self.recent) > self.keep:
            old = self.recent.popleft()
            with contextlib.suppress(OSError):
                old.unlink()
                self.deleted += 1

    def close(self) -> None:
        if self.sniffer is None:
            return
        packets = self.sniffer.close()
        if self._path is not None:
            if packets:
                self._file(self._path, None)
            else:
                with contextlib.suppress(OSError):
                    self._path.unlink()
        self._path = None

    def to_dict(self) -> dict[str, Any]:
        return {"directory": str(self.directory), "keep": self.keep, "recent": [p.name for p in self.recent],
                "findings": [p.name for p in self.pinned], "deleted": self.deleted, "error": self.error,
                "packets": self.sniffer.packets if self.sniffer is not None else 0}


__all__ = ["PcapRing"]
