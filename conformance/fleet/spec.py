"""Fleet files: a TOML list of boxes, checked before anything runs.

A fleet file has one ``[[box]]`` table per box and an optional ``[defaults]`` table::

    [defaults]
    time_out = 500                # any setting of `isight-conformance run`, applied to every box

    [[box]]
    name = "line1-cell3"          # names the box's report directory: letters, digits, . _ -
    target = "10.0.1.13:9004"     # no target: the box's run starts its own bundled reference box
    udp_target = "10.0.1.13:9004"
    first_index = 1               # profile and suite settings, as the run flags without the dashes
    expected_failures = ["T2-01"] # case IDs this box is known to fail

A setting is a ``run`` flag without its leading dashes (``udp-target`` and ``udp_target``
are the same key; a profile setting may also be named by its profile field, e.g.
``time_out_ms``). Values are TOML strings, numbers or booleans; ``cases``, ``exclude``
and ``sequence`` also take a list. Relative ``sequence`` paths are relative to the
fleet file. Settings given on the command line next to ``--targets`` apply to every box
and take precedence over the file. Every problem is a :class:`FleetFileError` naming
the file and line.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..runtime.profile_options import PROFILE_OPTIONS
from ..runtime.settings import SUITE_OPTIONS, SuiteSettings, add_suite_options

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")
#: settings the fleet sets for every box itself
FLEET_OWNED = {"report-dir": "each box writes to DIR/<name>/ (give --report-dir DIR on the command line)",
               "pcap-dir": "each box writes its pcaps to DIR/<name>/pcaps/"}
#: settings that take a list
MULTI = {"cases", "exclude", "sequence"}
#: settings whose values must be TOML strings (a bare 9004 is not a target)
STRINGS = {"target", "udp-target", "stream-target", "target-label", "cases", "exclude", "sequence"}


@dataclass(frozen=True)
class Setting:
    key: str  # "udp-target": the flag without its dashes
    flag: str  # "--udp-target"
    dest: str  # the argparse dest


def _settings() -> dict[str, Setting]:
    out: dict[str, Setting] = {}
    for flag, kwargs in SUITE_OPTIONS:
        out[flag[2:]] = Setting(flag[2:], flag, kwargs["dest"])
    for opt in PROFILE_OPTIONS:
        out[opt.flag[2:]] = Setting(opt.flag[2:], opt.flag, opt.dest)
    for opt in PROFILE_OPTIONS:  # a profile field name is an alias (time_out_ms for --time-out)
        out.setdefault(opt.field.replace("_", "-"), out[opt.flag[2:]])
    for key in FLEET_OWNED:
        out.pop(key, None)
    return out


SETTINGS: dict[str, Setting] = _settings()


def normal_key(key: str) -> str:
    return key.strip().lower().replace("_", "-")


class FleetFileError(ValueError):
    """A problem in a fleet file, at a line (0: the file as a whole)."""

    def __init__(self, path: Path | str, line: int, message: str) -> None:
        self.path, self.line, self.message = Path(path), line, message
        super().__init__(f"{path}:{line}: {message}" if line else f"{path}: {message}")


@dataclass(frozen=True)
class BoxSpec:
    name: str
    line: int  # the line of its [[box]] table
    #: setting key -> its values as command-line strings (one, or several for cases/exclude/sequence)
    settings: dict[str, tuple[str, ...]] = field(default_factory=dict)
    expected_failures: tuple[str, ...] | None = None

    @property
    def target(self) -> str | None:
        values = self.settings.get("target")
        return values[0] if values else None

    def flags(self) -> list[str]:
        """The ``run`` flags of this box (``--flag=value``), without the report directories."""
        return [f"{SETTINGS[key].flag}={value}" for key, values in self.settings.items() for value in values]


@dataclass(frozen=True)
class FleetSpec:
    path: Path
    boxes: tuple[BoxSpec, ...]


class _ParseError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> Any:  # never exit: the caller names the line
        raise _ParseError(message)


def _option_parser() -> argparse.ArgumentParser:
    parser = _Parser(add_help=False, allow_abbrev=False)
    add_suite_options(parser.add_argument)
    return parser


# -- where things are in the text ---------------------------------------------------------------
_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"""^\s*(?:"([^"]+)"|'([^']+)'|([A-Za-z0-9_-]+))\s*=""")


class Lines:
    """The line of each table and key of a fleet file (1-based), found in its text."""

    def __init__(self, text: str) -> None:
        self.boxes: list[tuple[int, dict[str, int]]] = []  # per [[box]]: header line, key -> line
        self.tables: dict[str, tuple[int, dict[str, int]]] = {}  # [name]: header line, keys
        self.top: dict[str, int] = {}  # top-level keys
        keys = self.top
        for number, line in enumerate(text.splitlines(), start=1):
            header = _HEADER.match(line)
            if header:
                name = header.group(2).strip().strip("\"'")
                keys = {}
                if header.group(1) == "[[" and name == "box":
                    self.boxes.append((number, keys))
                else:
                    self.tables.setdefault(name, (number, keys))
                    self.top.setdefault(name, number)
                continue
            key = _KEY.match(line)
            if key:
                raw = next(g for g in key.groups() if g is not None)
                keys.setdefault(raw, number)

    @staticmethod
    def _find(keys: dict[str, int], key: str, default: int) -> int:
        if key in keys:
            return keys[key]
        return next((line for raw, line in keys.items() if normal_key(raw) == normal_key(key)), default)

    def box(self, index: int, key: str | None = None) -> int:
        if index >= len(self.boxes):
            return 0
        header, keys = self.boxes[index]
        return self._find(keys, key, header) if key else header

    def table(self, name: str, key: str | None = None) -> int:
        header, keys = self.tables.get(name, (0, {}))
        return self._find(keys, key, header) if key else header


# -- values ------------------------------------------------------------------------------------------
def _as_text(value: Any) -> str | None:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (str, int, float)):
        return str(value)
    return None


def setting_values(key: str, value: Any, base: Path | None = None) -> tuple[str, ...]:
    """A setting's TOML (or argparse) value as command-line strings; ValueError if malformed."""
    items = value if isinstance(value, (list, tuple)) else [value]
    if isinstance(value, (list, tuple)) and key not in MULTI:
        raise ValueError("takes one value, not a list")
    out = []
    for item in items:
        text = _as_text(item)
        if text is None:
            raise ValueError(f"a {type(item).__name__} is not a value for it (a string, number or boolean)")
        if key in STRINGS and not isinstance(item, str):
            raise ValueError(f"write it as a string (in quotes), e.g. {key.replace('-', '_')} = \"{text}\"")
        if key == "sequence" and base is not None and not Path(text).is_absolute():
            text = str(base / text)
        out.append(text)
    return tuple(out)


_TYPES = {"int": "a whole number", "float": "a number", "_bool": "strict or lenient (or true/false)"}


def _plain(message: str) -> str:
    """argparse's message without its "argument --x:" prefix and its type-function names."""
    message = re.sub(r"^argument [^:]+: ", "", message)
    m = re.match(r"^invalid (\w+) value: (.*)$", message)
    return f"expected {_TYPES.get(m.group(1), m.group(1))}, not {m.group(2)}" if m else message


def check_settings(settings: Mapping[str, tuple[str, ...]], parser: argparse.ArgumentParser) -> None:
    """ValueError (one line) if these settings are not a valid ``run`` configuration."""
    flags = [f"{SETTINGS[k].flag}={v}" for k, values in settings.items() for v in values]
    try:
        ns, rest = parser.parse_known_args(flags)
    except _ParseError as exc:
        raise ValueError(_plain(str(exc))) from None
    if rest:
        raise ValueError(f"not understood: {' '.join(rest)}")
    SuiteSettings.resolve(lambda dest: getattr(ns, dest, None))


def _table_settings(table: Mapping[str, Any], where: Any, path: Path, parser: argparse.ArgumentParser,
                    skip: tuple[str, ...] = ()) -> dict[str, tuple[str, ...]]:
    """The settings of one table, each checked on its own (an error names its key's line)."""
    out: dict[str, tuple[str, ...]] = {}
    first: dict[str, str] = {}
    for raw, value in table.items():
        key = normal_key(raw)
        if key in skip:
            continue
        line = where(raw)
        if key in FLEET_OWNED:
            raise FleetFileError(path, line, f"{raw}: set by the fleet: {FLEET_OWNED[key]}")
        if key not in SETTINGS:
            known = ", ".join(sorted({s.key.replace("-", "_") for s in SETTINGS.values()}))
            raise FleetFileError(path, line, f"unknown setting {raw!r} (known: name, expected_failures, {known})")
        canon = SETTINGS[key].key
        if canon in out:
            raise FleetFileError(path, line, f"{raw}: set twice in this table (also as {first[canon]})")
        first[canon] = raw
        try:
            out[canon] = setting_values(canon, value, path.parent)
            check_settings({canon: out[canon]}, parser)
        except ValueError as exc:
            raise FleetFileError(path, line, f"{raw} = {_show(value)}: {exc}") from None
    return out


def _show(value: Any) -> str:
    if isinstance(value, str):
        return repr(value) if len(value) < 80 else repr(value[:77] + "...")
    return str(value).lower() if isinstance(value, bool) else str(value)[:80]


def parse_fleet(text: str, path: Path | str = "<fleet>",
                overrides: Mapping[str, tuple[str, ...]] | None = None) -> FleetSpec:
    """Parse and check a fleet file's text. ``overrides`` (setting key -> values, from the
    command line) apply to every box over the file's settings."""
    path = Path(path)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = re.search(r"\s*\(at line (\d+), column (\d+)\)$", msg)
        if m:
            raise FleetFileError(path, int(m.group(1)), f"not valid TOML: {msg[:m.start()]} (column {m.group(2)})") from None
        raise FleetFileError(path, 0, f"not valid TOML: {msg}") from None
    lines = Lines(text)
    parser = _option_parser()
    for key in doc:
        if key not in ("box", "defaults"):
            raise FleetFileError(path, lines.top.get(key, 0),
                                 f"unknown top-level key {key!r} (a fleet file has [[box]] tables and one [defaults])")
    defaults_table = doc.get("defaults", {})
    if not isinstance(defaults_table, dict):
        raise FleetFileError(path, lines.top.get("defaults", 0), "defaults must be a table: [defaults]")
    for key in ("name", "expected-failures"):
        if any(normal_key(k) == key for k in defaults_table):
            raw = next(k for k in defaults_table if normal_key(k) == key)
            raise FleetFileError(path, lines.table("defaults", raw), f"{raw} belongs in each [[box]] table")
    defaults = _table_settings(defaults_table, lambda raw: lines.table("defaults", raw), path, parser)
    boxes = doc.get("box")
    if boxes is None:
        raise FleetFileError(path, 0, "no [[box]] table: a fleet file lists its boxes as [[box]] tables")
    if not isinstance(boxes, list):
        raise FleetFileError(path, lines.top.get("box", 0), "write each box as a [[box]] table (an array of tables)")
    seen: dict[str, int] = {}
    out = []
    for index, table in enumerate(boxes):
        box_line = lines.box(index)
        if not isinstance(table, dict):
            raise FleetFileError(path, box_line or lines.top.get("box", 0), "each box must be a table")
        out.append(_box(table, index, lines, path, parser, defaults, overrides or {}, seen))
    if not out:
        raise FleetFileError(path, lines.top.get("box", 0), "no boxes listed")
    return FleetSpec(path, tuple(out))


def _box(table: dict[str, Any], index: int, lines: Lines, path: Path, parser: argparse.ArgumentParser,
         defaults: dict[str, tuple[str, ...]], overrides: Mapping[str, tuple[str, ...]],
         seen: dict[str, int]) -> BoxSpec:
    box_line = lines.box(index)
    keys = {normal_key(k): k for k in table}
    if "name" not in keys:
        raise FleetFileError(path, box_line, "this [[box]] has no name (name = \"...\")")
    name = table[keys["name"]]
    name_line = lines.box(index, keys["name"])
    if not isinstance(name, str) or not NAME.match(name):
        raise FleetFileError(path, name_line, f"name = {_show(name)}: a name is 1-64 letters, digits, '.', '_' "
                             "or '-', starting with a letter or digit (it names the box's report directory)")
    if name.casefold() in seen:
        raise FleetFileError(path, name_line, f"duplicate box name {name!r} (first at line {seen[name.casefold()]})")
    seen[name.casefold()] = name_line
    expected = None
    if "expected-failures" in keys:
        raw = keys["expected-failures"]
        value = table[raw]
        if not isinstance(value, list) or not all(isinstance(v, str) and v.strip() for v in value):
            raise FleetFileError(path, lines.box(index, raw),
                                 f"{raw} = {_show(value)}: give a list of case IDs, e.g. [\"T2-01\", \"R5-02\"]")
        expected = tuple(dict.fromkeys(v.strip() for v in value))
    own = _table_settings(table, lambda raw: lines.box(index, raw), path, parser,
                          skip=("name", "expected-failures"))
    settings = {**defaults, **own, **overrides}
    try:
        check_settings(settings, parser)
    except ValueError as exc:
        raise FleetFileError(path, box_line, f"box {name!r}: {exc}") from None
    return BoxSpec(name=name, line=box_line, settings=settings, expected_failures=expected)


def load_fleet(path: Path | str, overrides: Mapping[str, tuple[str, ...]] | None = None) -> FleetSpec:
    """Read and check a fleet file (FleetFileError for a bad one, OSError if unreadable)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise FleetFileError(path, 0, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    return parse_fleet(text, path, overrides)


def command_line_overrides(args: argparse.Namespace) -> dict[str, tuple[str, ...]]:
    """The ``run`` settings given on the command line (next to ``--targets``), as box settings."""
    out: dict[str, tuple[str, ...]] = {}
    for setting in {s.key: s for s in SETTINGS.values()}.values():
        value = getattr(args, setting.dest, None)
        if value is not None:
            out[setting.key] = setting_values(setting.key, value)
    return out
