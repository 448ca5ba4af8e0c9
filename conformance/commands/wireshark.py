"""``isight-conformance wireshark``: put the iSight dissector where Wireshark looks.

``--path`` prints the personal Lua plugins folder: what ``tshark -G folders`` calls
"Personal Lua Plugins" when tshark is on PATH, else Wireshark's documented default
(Linux and macOS ``~/.local/lib/wireshark/plugins``, Windows
``%APPDATA%\\Wireshark\\plugins``). ``--install`` copies ``isight.lua`` there (creating
the folder), ``--print`` writes it to stdout.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Mapping
from importlib import resources
from pathlib import Path

from ..i18n import N_, _
from ..model.exit_codes import EXIT_OK, EXIT_USAGE
from .registry import Command

PLUGIN_NAME = "isight.lua"
FOLDER_KEY = "Personal Lua Plugins"
TSHARK_TIMEOUT_S = 30.0


def add_arguments(p: argparse.ArgumentParser) -> None:
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--path", action="store_true", help=_("print the personal Lua plugins folder"))
    what.add_argument("--install", action="store_true", help=_("copy isight.lua into that folder (created if needed)"))
    what.add_argument("--print", action="store_true", help=_("write isight.lua to stdout"))


def dissector_bytes() -> bytes:
    """The dissector shipped in the package."""
    return resources.files("conformance").joinpath("wireshark").joinpath(PLUGIN_NAME).read_bytes()


def parse_folders(text: str) -> Path | None:
    """The "Personal Lua Plugins" folder from ``tshark -G folders`` output (None if absent)."""
    for line in text.splitlines():
        key, sep, value = line.partition(":")  # the key has no colon; a Windows path does
        if sep and key.strip() == FOLDER_KEY and value.strip():
            return Path(value.strip())
    return None


def ask_tshark(tshark: str, env: Mapping[str, str] | None = None) -> Path | None:
    """What tshark says the personal Lua plugins folder is; None if it cannot say."""
    try:
        proc = subprocess.run([tshark, "-G", "folders"], capture_output=True, text=True, timeout=TSHARK_TIMEOUT_S,
                              env=None if env is None else dict(env), errors="replace")
    except (OSError, subprocess.SubprocessError):
        return None
    return parse_folders(proc.stdout) if proc.returncode == 0 else None


def default_folder(platform: str = sys.platform, env: Mapping[str, str] | None = None) -> Path:
    """Wireshark's documented personal (Lua) plugin folder for ``platform`` (User's Guide,
    "Plugin folders")."""
    env = os.environ if env is None else env
    if platform.startswith("win"):
        appdata = env.get("APPDATA") or str(Path(env.get("USERPROFILE") or Path.home()) / "AppData" / "Roaming")
        return Path(appdata) / "Wireshark" / "plugins"
    home = env.get("HOME") or str(Path.home())
    return Path(home) / ".local" / "lib" / "wireshark" / "plugins"


def plugins_folder(tshark: str | None = None, platform: str = sys.platform,
                   env: Mapping[str, str] | None = None) -> tuple[Path, str]:
    """(folder, how it was found): tshark's answer when ``tshark`` is given and answers, else the default."""
    if tshark:
        found = ask_tshark(tshark, env)
        if found is not None:
            return found, f"from {tshark} -G folders"
    return default_folder(platform, env), "Wireshark's documented default (tshark not found or did not say)"


def install(folder: Path) -> tuple[Path, str]:
    """Copy the dissector into ``folder`` atomically; (the file, "installed"/"replaced"/"up to date").
    Raises OSError."""
    data = dissector_bytes()
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / PLUGIN_NAME
    if target.is_file() and target.read_bytes() == data:
        return target, "up to date"
    state = "replaced" if target.exists() else "installed"
    fd, tmp = tempfile.mkstemp(prefix=".isight-", suffix=".lua.tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target, state


def main_wireshark(args: argparse.Namespace) -> int:
    if args.print:
        sys.stdout.flush()
        sys.stdout.buffer.write(dissector_bytes())
        sys.stdout.buffer.flush()
        return EXIT_OK
    folder, how = plugins_folder(shutil.which("tshark"))
    if args.path:
        print(folder)
        return EXIT_OK
    try:
        target, state = install(folder)
    except OSError as exc:
        print(f"isight-conformance wireshark: cannot install into {folder}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    print(f"{PLUGIN_NAME} {state}: {target} ({how}). "
          "Restart Wireshark or use Analyze > Reload Lua Plugins (Ctrl+Shift+L); check with "
          "'tshark -G protocols | grep isight'.")
    return EXIT_OK


COMMAND = Command(
    "wireshark", N_("print, or install into, Wireshark's personal Lua plugins folder the iSight dissector"),
    add_arguments, main_wireshark,
    description=N_("The Wireshark dissector for iSight (isight.lua, see conformance/wireshark/README.md). "
        "--path prints the personal Lua plugins folder (asked of tshark when it is on PATH, else Wireshark's "
        "documented default for this OS), --install copies isight.lua there, --print writes it to stdout. "
        "Exit status: 0, or 2 when the folder cannot be written."),
)
