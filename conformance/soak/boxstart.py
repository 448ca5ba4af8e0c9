"""The box a soak talks to: a ``--target``, or one the soak starts itself and watches.

Without ``--target`` the soak starts the bundled reference box, like ``run``, but as a child
process (``isight-conformance serve --port 0``) so that its RSS, descriptors, threads and CPU are
the box's, not the soak's. ``--restart-cmd CMD`` starts the box with CMD instead (the fuzzer's
:class:`~conformance.fuzz.box_process.BoxProcess`); without ``--target`` its address is read from
its first output line ``listening tcp HOST:PORT``, the line ``serve`` and the project's test
boxes print.
"""

from __future__ import annotations

import re
import shlex
import sys
import time

from ..fuzz.box_process import BoxProcess
from ..harness.target import Target
from ..protocol import Profile
from ..runtime.profile_options import profile_flags

LISTENING = re.compile(rb"listening tcp (\S+):(\d+)")
#: how long a started box may take to print where it listens
START_S = 15.0


def bundled_command(profile: Profile) -> str:
    """The command that serves the bundled reference box on a free loopback port, TCP only."""
    words = [sys.executable, "-m", "conformance", "serve", "--host", "127.0.0.1", "--port", "0", "--no-udp",
             *profile_flags(profile)]
    return " ".join(shlex.quote(w) for w in words)


def start_box(cmd: str, target: Target | None) -> tuple[BoxProcess, Target]:
    """Start the box with ``cmd``; its target as given, or from its ``listening tcp`` line. ValueError if it fails."""
    box = BoxProcess(cmd, log=lambda text: print(text, file=sys.stderr))
    try:
        inc = box.start()
    except (RuntimeError, OSError) as exc:
        raise ValueError(f"--restart-cmd: {exc}") from None
    if target is not None:
        return box, target
    deadline = time.monotonic() + START_S
    while time.monotonic() < deadline:
        match = LISTENING.search(bytes(inc.ring))
        if match:
            host = match.group(1).decode("ascii", "replace").strip("[]")
            return box, Target(host, int(match.group(2)))
        if inc.status() is not None:
            break
        time.sleep(0.05)
    box.close()
    raise ValueError(f"the box started by {cmd!r} printed no 'listening tcp HOST:PORT' line within "
                     f"{START_S:g} s; give --target")


__all__ = ["bundled_command", "start_box"]
