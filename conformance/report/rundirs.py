"""Default report and pcap directories that two runs never share.

``run``, ``certify-robot`` and ``fuzz`` write, by default, into ``reports/<stamp>`` and
``pcaps/<stamp>`` (stamp ``YYYYmmdd-HHMMSS``). Two runs started in the same second
would share them; :func:`unique_run_dirs` creates the directories itself, with
``mkdir`` (never ``exist_ok``: the kernel decides who gets a name), and when a name is
taken tries ``<stamp>-2``, ``<stamp>-3``, ... The same suffix is used under every
parent, so a run's report and pcap directories keep matching names.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
from pathlib import Path

#: where a package's pcaps go (``--report-dir DIR`` without ``--pcap-dir``): ``DIR/pcaps``
PACKAGE_PCAPS = "pcaps"
#: tries before giving up (a directory full of runs from one second is a bug elsewhere)
MAX_SUFFIX = 1000


def stamp(now: _dt.datetime | None = None) -> str:
    """``20240601-101500``: the local time a run started, to the second."""
    return (now or _dt.datetime.now()).strftime("%Y%m%d-%H%M%S")


def unique_run_dirs(name: str, *parents: Path | str) -> tuple[Path, ...]:
    """Create ``parent/<name>`` under every parent (``<name>-2``, ``-3``, ... when any of
    them exists already) and return them, in the order of ``parents``.

    Each directory is created by this call (it did not exist before), so concurrent
    callers never get the same one. Parents are created as needed. Raises OSError
    (e.g. permission denied, or no free name within MAX_SUFFIX tries).
    """
    bases = [Path(p) for p in parents]
    for base in bases:
        base.mkdir(parents=True, exist_ok=True)
    for n in range(1, MAX_SUFFIX + 1):
        leaf = name if n == 1 else f"{name}-{n}"
        made: list[Path] = []
        try:
            for base in bases:
                path = base / leaf
                path.mkdir()  # FileExistsError: someone else's (or an old run's)
                made.append(path)
        except FileExistsError:
            for path in reversed(made):  # ours and still empty: give the name back
                with contextlib.suppress(OSError):
                    path.rmdir()
            continue
        return tuple(made)
    raise OSError(f"no free run directory named {name}[-N] under {', '.join(map(str, bases))}")


def drop_if_empty(*paths: Path | None) -> None:
    """Remove run directories a command made and left empty (it stopped before writing anything: no robot
    came, it could not listen, a setting was refused), so a failed start leaves nothing behind. Only an
    empty directory goes (``rmdir``); pass only directories the command made itself."""
    for path in paths:
        if path is not None:
            with contextlib.suppress(OSError):
                path.rmdir()


def default_run_dirs(report_dir: Path | str | None, pcap_dir: Path | str | None, pcaps: bool = True,
                     prefix: str = "") -> tuple[Path, Path | None]:
    """(report dir, pcap dir or None when ``pcaps`` is False): the given ones as they are,
    the missing ones created as ``reports/<prefix><stamp>[-N]`` and ``pcaps/<prefix><stamp>[-N]``
    (relative to the current directory). A given report directory is one package: its pcaps go to
    ``<report dir>/pcaps`` unless ``pcap_dir`` says otherwise, so the directory travels whole."""
    wanted: dict[str, Path] = {}
    if report_dir is None:
        wanted["report"] = Path("reports")
    elif pcap_dir is None:
        pcap_dir = Path(report_dir) / PACKAGE_PCAPS
    if pcaps and pcap_dir is None:
        wanted["pcap"] = Path("pcaps")
    made = dict(zip(wanted, unique_run_dirs(prefix + stamp(), *wanted.values()))) if wanted else {}
    report = Path(report_dir) if report_dir is not None else made["report"]
    if not pcaps:
        return report, None
    return report, Path(pcap_dir) if pcap_dir is not None else made["pcap"]
