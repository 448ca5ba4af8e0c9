"""The bundled reference box, started on loopback for a run that names no target.

One helper for every command that needs it (``run``, the pytest plugin, ``fuzz``, ``replay``)::

    with bundled_or_target(target, udp_target, profile) as (target, udp_target, box):
        ...                           # box: None when a target was given, else box.label, box.restart()
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from ..harness.target import Target
from ..protocol import Profile
from .behaviour import BoxConfig
from .loop import BoxThread


@dataclass
class Bundled:
    thread: BoxThread
    target: Target
    udp_target: Target | None
    config: BoxConfig

    @property
    def label(self) -> str:
        return f"bundled reference box at {self.target}"

    def restart(self) -> None:
        """A fresh box on the same ports (fuzzing restarts it to tell which input killed it)."""
        self.thread.stop()
        self.thread = BoxThread(self.config, host="127.0.0.1", port=self.target.port).start()

    def stop(self) -> None:
        self.thread.stop()


def start_bundled(profile: Profile, config: BoxConfig | None = None) -> Bundled:
    """Start the reference box (TCP and UDP) on 127.0.0.1, free ports, in this profile."""
    config = config or BoxConfig(profile=profile)
    thread = BoxThread(config, host="127.0.0.1", port=0).start()
    udp = Target("127.0.0.1", thread.udp_port) if thread.udp_port else None
    return Bundled(thread, Target("127.0.0.1", thread.tcp_port), udp, config)


@contextmanager
def bundled_or_target(target: Target | None, udp_target: Target | None,
                      profile: Profile) -> Iterator[tuple[Target, Target | None, Bundled | None]]:
    """The box a command talks to, as ``(target, udp target, the bundled box or None)``: ``target``
    as given, or, when it is None, the bundled reference box, started for the block and stopped
    after it (its UDP port unless ``udp_target`` names another). ``run``, ``fuzz``, ``replay`` and
    the pytest plugin's session all start it here."""
    if target is not None:
        yield target, udp_target, None
        return
    box = start_bundled(profile)
    try:
        yield box.target, udp_target or box.udp_target, box
    finally:
        box.stop()
