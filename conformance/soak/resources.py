"""The box's resources, when it runs on this host: RSS, open file descriptors, threads, CPU and
the TCP connections it holds, read with psutil (one portable library for what /proc, ``lsof``
and ``ps`` each give a piece of). And the soak's own RSS, to show it stays flat.

The connections the box holds are split: those whose peer is a half-open connection the soak
itself keeps open (a robot that vanished: the box cannot know, and the soak does not count them
against it), those in CLOSE_WAIT (the robot closed, the box did not: S5), and the rest.
"""

from __future__ import annotations

import os
from typing import Any

import psutil

SHELLS = {"sh", "bash", "dash", "zsh"}


class BoxGone(Exception):
    """The box's process ended."""


def own_rss_mb() -> float:
    return float(psutil.Process(os.getpid()).memory_info().rss) / 2**20


class BoxProbe:
    """Samples one process (a shell that started the box: its only child)."""

    def __init__(self, pid: int) -> None:
        try:
            proc = psutil.Process(pid)
            if proc.name() in SHELLS:
                children = proc.children()
                if len(children) == 1:
                    proc = children[0]
            proc.cpu_percent(None)  # primes the CPU counter: the next call measures since now
        except psutil.NoSuchProcess:
            raise ValueError(f"--box-pid {pid}: no such process") from None
        except psutil.AccessDenied:
            raise ValueError(f"--box-pid {pid}: not allowed to read that process") from None
        self.proc = proc
        self.pid = proc.pid

    def alive(self) -> bool:
        try:
            return self.proc.is_running() and self.proc.status() != psutil.STATUS_ZOMBIE
        except psutil.Error:
            return False

    def sample(self, ghost_ports: set[int]) -> dict[str, float | None]:
        """The box's figures now; raises BoxGone when it ended."""
        proc = self.proc
        try:
            with proc.oneshot():
                rss = proc.memory_info().rss / 2**20
                fds = proc.num_fds() if hasattr(proc, "num_fds") else None
                threads = proc.num_threads()
                cpu = proc.cpu_percent(None)
            conns = proc.net_connections(kind="tcp")
        except psutil.NoSuchProcess:
            raise BoxGone(f"the box's process {self.pid} ended") from None
        except psutil.AccessDenied:
            return {"rss_mb": None, "fds": None, "threads": None, "cpu_percent": None, "connections": None}
        live = [c for c in conns if c.status != psutil.CONN_LISTEN and c.raddr]
        half_open = sum(1 for c in live if c.raddr.port in ghost_ports)
        close_wait = sum(1 for c in live if c.status == psutil.CONN_CLOSE_WAIT)
        out: dict[str, float | None] = {
            "rss_mb": round(rss, 3), "fds": None if fds is None else float(fds - half_open), "threads": float(threads),
            "cpu_percent": round(cpu, 2), "connections": float(len(live) - half_open),
            "half_open_held": float(half_open), "close_wait": float(close_wait),
        }
        return out


def describe(probe: BoxProbe | None) -> dict[str, Any] | None:
    if probe is None:
        return None
    try:
        return {"pid": probe.pid, "name": probe.proc.name(), "cmdline": " ".join(probe.proc.cmdline())[:300]}
    except psutil.Error:
        return {"pid": probe.pid}


__all__ = ["BoxGone", "BoxProbe", "describe", "own_rss_mb"]
