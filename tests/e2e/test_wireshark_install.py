"""``isight-conformance wireshark``: the dissector where Wireshark looks."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conformance.commands.wireshark import (
    PLUGIN_NAME,
    default_folder,
    dissector_bytes,
    install,
    parse_folders,
    plugins_folder,
)

ROOT = Path(__file__).resolve().parents[2]
TSHARK = shutil.which("tshark")
needs_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed: cannot ask it for its folders "
                                                        "or check that it loads the installed plugin")


def cli(*argv: str, home: Path, path_env: str | None = None) -> subprocess.CompletedProcess[bytes]:
    env = {**os.environ, "HOME": str(home)}
    if path_env is not None:
        env["PATH"] = path_env
    return subprocess.run([sys.executable, "-m", "conformance", "wireshark", *argv], capture_output=True, env=env,
                          timeout=120, cwd=home if home.is_dir() else home.parent)


# -- finding the folder ----------------------------------------------------------------------
LINUX_FOLDERS = """Temp:                \t/tmp
Personal configuration:\t/home/u/.config/wireshark
Personal Plugins:    \t/home/u/.local/lib/wireshark/plugins/4.0
Personal Lua Plugins:\t/home/u/.local/lib/wireshark/plugins
Global Lua Plugins:  \t/usr/lib/x86_64-linux-gnu/wireshark/plugins
"""
WINDOWS_FOLDERS = "Personal Plugins:\tC:\\Users\\u\\AppData\\Roaming\\Wireshark\\plugins\\4.2\r\n" \
                  "Personal Lua Plugins:\tC:\\Users\\u\\AppData\\Roaming\\Wireshark\\plugins\r\n"


def test_parse_folders_takes_the_personal_lua_line_only():
    assert parse_folders(LINUX_FOLDERS) == Path("/home/u/.local/lib/wireshark/plugins")
    assert str(parse_folders(WINDOWS_FOLDERS)) == str(Path("C:\\Users\\u\\AppData\\Roaming\\Wireshark\\plugins"))
    assert parse_folders("Personal Plugins:\t/x/4.0\n") is None
    assert parse_folders("") is None and parse_folders("Personal Lua Plugins:\t\n") is None


def test_documented_defaults_per_os():
    assert default_folder("linux", {"HOME": "/home/u"}) == Path("/home/u/.local/lib/wireshark/plugins")
    assert default_folder("darwin", {"HOME": "/Users/u"}) == Path("/Users/u/.local/lib/wireshark/plugins")
    assert default_folder("win32", {"APPDATA": "C:\\Users\\u\\AppData\\Roaming"}) == \
        Path("C:\\Users\\u\\AppData\\Roaming") / "Wireshark" / "plugins"
    assert default_folder("win32", {"USERPROFILE": "C:\\Users\\u"}) == \
        Path("C:\\Users\\u") / "AppData" / "Roaming" / "Wireshark" / "plugins"


def test_without_tshark_the_default_is_used(tmp_path):
    folder, how = plugins_folder(None, "linux", {"HOME": str(tmp_path)})
    assert folder == tmp_path / ".local" / "lib" / "wireshark" / "plugins" and "default" in how
    missing = str(tmp_path / "no-such-tshark")
    folder2, how2 = plugins_folder(missing, "linux", {"HOME": str(tmp_path)})
    assert folder2 == folder and "default" in how2


@needs_tshark
def test_path_is_what_tshark_says_for_this_home(tmp_path):
    proc = cli("--path", home=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert Path(proc.stdout.decode().strip()) == tmp_path / ".local" / "lib" / "wireshark" / "plugins"


def test_path_without_tshark_on_path_falls_back_to_the_default(tmp_path):
    bare = tmp_path / "bin"
    bare.mkdir()
    proc = cli("--path", home=tmp_path, path_env=str(bare))
    assert proc.returncode == 0, proc.stderr
    assert Path(proc.stdout.decode().strip()) == default_folder(sys.platform, {**os.environ, "HOME": str(tmp_path)})


# -- installing ------------------------------------------------------------------------------
def test_install_creates_the_folder_and_copies_the_dissector(tmp_path):
    folder = tmp_path / "a" / "b"
    target, state = install(folder)
    assert state == "installed" and target == folder / PLUGIN_NAME
    assert target.read_bytes() == dissector_bytes() == (ROOT / "conformance" / "wireshark" / PLUGIN_NAME).read_bytes()
    assert install(folder) == (target, "up to date")
    target.write_bytes(b"-- old version\n")
    assert install(folder) == (target, "replaced") and target.read_bytes() == dissector_bytes()
    assert sorted(p.name for p in folder.iterdir()) == [PLUGIN_NAME]  # no temp file left


def test_install_where_the_folder_cannot_be_made_is_one_line_and_exit_2(tmp_path):
    home = tmp_path / "not-a-dir"
    home.write_text("x")
    proc = cli("--install", home=home, path_env=str(tmp_path))  # no tshark: the default under HOME
    assert proc.returncode == 2
    err = proc.stderr.decode()
    assert len(err.strip().splitlines()) == 1 and "cannot install" in err and "Traceback" not in err


@needs_tshark
def test_installed_plugin_is_listed_and_loaded_by_tshark(tmp_path):
    proc = cli("--install", home=tmp_path)
    assert proc.returncode == 0, proc.stderr
    installed = tmp_path / ".local" / "lib" / "wireshark" / "plugins" / PLUGIN_NAME
    assert str(installed) in proc.stdout.decode() and installed.read_bytes() == dissector_bytes()
    env = {**os.environ, "HOME": str(tmp_path)}
    plugins = subprocess.run([TSHARK or "tshark", "-G", "plugins"], capture_output=True, text=True, env=env,
                             timeout=120)
    rows = [line.split("\t") for line in plugins.stdout.splitlines() if line.startswith(PLUGIN_NAME)]
    assert rows and rows[0][-1] == str(installed), plugins.stdout[-2000:]
    protocols = subprocess.run([TSHARK or "tshark", "-G", "protocols"], capture_output=True, text=True, env=env,
                               timeout=120)
    assert any(line.split("\t")[-1] == "isight" for line in protocols.stdout.splitlines())


def test_print_writes_the_dissector_byte_for_byte(tmp_path):
    proc = cli("--print", home=tmp_path)
    assert proc.returncode == 0 and proc.stdout == dissector_bytes()


def test_one_action_is_required(tmp_path):
    proc = cli(home=tmp_path)
    assert proc.returncode == 2 and b"one of the arguments" in proc.stderr
