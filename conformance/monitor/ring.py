"""The monitor's pcapng evidence: a ring of files, like dumpcap's ``-b files:N -b filesize:KB``.

:class:`Ring` writes Enhanced Packet Blocks into ``<dir>/monitor_<NNNNN>.pcapng``. When
the current file reaches ``file_mb`` MB the next one starts, and only the newest
``files`` files are kept (the oldest is deleted), so the disk used stays below about
``files * file_mb`` MB whatever the duration. Every file starts with its own section
header and interface (it is readable on its own); its section comment names the first
frame number it holds, counted from the monitor's start (the numbers findings cite).
Every write is whole blocks (the file is unbuffered): a monitor killed at any point
leaves files that Wireshark reads up to the last block.
"""

from __future__ import annotations

import os
from collections import deque
from pathlib import Path

from ..evidence.pcapng import LINKTYPE_ETHERNET, PcapNgFile

__all__ = ["Ring"]

APPLICATION = "isight-conformance monitor"


class Ring:
    def __init__(self, directory: Path, files: int = 10, file_mb: float = 100.0) -> None:
        if files < 1:
            raise ValueError(f"--ring must be at least 1, not {files}")
        if not 0 < file_mb <= 1 << 20:
            raise ValueError(f"--ring-mb must be in (0, 1048576], not {file_mb:g}")
        self.directory = directory
        self.files = files
        self.limit = int(file_mb * 1_000_000)
        self.kept: deque[tuple[Path, int]] = deque()  # (path, first frame) of the files on disk
        self.deleted = 0
        self.error: OSError | None = None
        self._file: PcapNgFile | None = None
        self._size = 0
        self._number = 0

    # -- writing -------------------------------------------------------------------------------
    def write(self, frame: bytes, t: float, no: int, comments: list[str] | None = None) -> None:
        """Frame ``no`` (Ethernet) at time ``t``; a new file first when the current one is full."""
        if self.error is not None:
            return
        if self._file is None or self._size >= self.limit:
            self._next(no)
            if self._file is None:
                return
        block = self._file.epb(frame, t, comments)
        self._file.write(block)
        self._size += len(block)
        if self._file.error is not None:
            self.error = self._file.error

    def _next(self, first_frame: int) -> None:
        if self._file is not None:
            self._file.close()
        self._number += 1
        path = self.directory / f"monitor_{self._number:05d}.pcapng"
        try:
            self._file = PcapNgFile(path, application=APPLICATION,
                                    comment=f"isight-conformance monitor: file {self._number}, frames from "
                                            f"{first_frame} (frame numbers in the monitor's findings count from its "
                                            "start)")
            self._file.add_interface(LINKTYPE_ETHERNET, "monitor", "robot <-> box as the robot sees it")
        except OSError as exc:
            self.error, self._file = exc, None
            return
        self._size = self._file_size(path)
        self.kept.append((path, first_frame))
        while len(self.kept) > self.files:
            old, _ = self.kept.popleft()
            try:
                old.unlink()
                self.deleted += 1
            except OSError:
                pass

    @staticmethod
    def _file_size(path: Path) -> int:
        try:
            return os.path.getsize(path)
        except OSError:
            return 0

    # -- facts ---------------------------------------------------------------------------------
    @property
    def current(self) -> Path | None:
        return self.kept[-1][0] if self.kept else None

    def disk_bytes(self) -> int:
        return sum(self._file_size(p) for p, _ in self.kept)

    def index(self) -> list[dict[str, object]]:
        """The files on disk, oldest first, each with the first frame number it holds."""
        return [{"file": p.name, "first_frame": first} for p, first in self.kept]

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
