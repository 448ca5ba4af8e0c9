"""The vendor's declaration (``--declared FILE``): what the box's maker says they built, where PROTOCOL.md
leaves a choice. An implementation conformance statement, as PICS/PIXIT forms hold one (ITU-T X.294).

The file is TOML (schema and an example: ``docs/DECLARED.md``, ``docs/declared.example.toml``); the keys sit at
the top level or under a ``[declared]`` table. The profile keys (:data:`PROFILE_KEYS`) become the run's profile:
the run is judged under the declared reading. A profile flag given on the command line that says otherwise is a
usage error. The other keys are only compared with what the run observed (:mod:`.declared_table`).
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from ..i18n import N_
from ..protocol import DEFAULT_PROFILE, Profile


@dataclass(frozen=True)
class Item:
    key: str
    clause: str
    label: str  # N_() marked: what the declaration is about
    kind: type  # int, str, bool
    choices: tuple[Any, ...] = ()


#: every declarable choice, in the table's order
ITEMS: tuple[Item, ...] = (
    Item("first_index", "B3", N_("index of the first block"), int, (0, 1)),
    Item("byte_order", "F4", N_("byte order of the header's multi-byte fields"), str, ("big", "little")),
    Item("crc", "F7", N_("UDP CRC-16 algorithm"), str),
    Item("crc_byte_order", "F7", N_("byte order of the UDP CRC"), str, ("big", "little")),
    Item("float_byte_order", "B4", N_("byte order of float32 and int32 values"), str, ("big", "little")),
    Item("tcp_check", "F6", N_("what the box accepts in a TCP check field"), str, ("zero", "zero-or-crc", "ignore")),
    Item("extension_e", "E1", N_("extension E (actions 26/27) implemented"), bool),
    Item("progidx_conflict", "E2", N_("where a ProgIdx 409 travels"), str, ("block", "error-code")),
    Item("cycle_state", "S3", N_("cycle state kept per box or per connection"), str, ("per-box", "per-connection")),
    Item("r6_framing", "R6", N_("how bad bytes are framed (R6 a, b or c)"), str,
         ("skip-announced", "resync-next-header", "close")),
    Item("connections", "S4", N_("connections served at once"), int),
    Item("answer_latency_ms", "T1", N_("answer latency promised (ms)"), int),
)
BY_KEY = {item.key: item for item in ITEMS}
#: the keys that are profile settings (the run is judged under them)
PROFILE_KEYS = ("first_index", "byte_order", "crc", "crc_byte_order", "float_byte_order", "tcp_check",
                "progidx_conflict")
#: R6's letters, as PROTOCOL.md names the legal framings
R6_LETTERS = {"a": "skip-announced", "b": "resync-next-header", "c": "close"}


#: the declaration's copy inside the package (the text as the vendor wrote it)
PACKAGE_COPY = "declared.toml"


@dataclass(frozen=True)
class Declaration:
    path: str  # where it was read from ("--declared FILE" in messages)
    values: dict[str, Any] = field(default_factory=dict)  # key -> declared value, in ITEMS order
    declared_by: str = ""
    text: str = ""  # the file as written, copied into the package

    def profile_changes(self) -> dict[str, Any]:
        return {k: v for k, v in self.values.items() if k in PROFILE_KEYS}

    def to_dict(self) -> dict[str, Any]:
        return {"file": PACKAGE_COPY, "source": self.path, "declared_by": self.declared_by,
                "values": dict(self.values)}


def _checked(item: Item, value: Any, where: str) -> Any:
    if item.key == "r6_framing" and isinstance(value, str):
        value = R6_LETTERS.get(value.strip().lower(), value)
    if item.kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise ValueError(f"{where}: {item.key} must be a whole number, not {value!r}")
    if item.kind is bool and not isinstance(value, bool):
        raise ValueError(f"{where}: {item.key} must be true or false, not {value!r}")
    if item.kind is str and not isinstance(value, str):
        raise ValueError(f"{where}: {item.key} must be a string, not {value!r}")
    if item.choices and value not in item.choices:
        raise ValueError(f"{where}: {item.key} must be one of {', '.join(map(str, item.choices))}, not {value!r}")
    if item.key in ("connections", "answer_latency_ms") and not 1 <= value <= 1_000_000:
        raise ValueError(f"{where}: {item.key} must be between 1 and 1000000")
    return value


def parse(text: str, where: str) -> Declaration:
    """A declaration from TOML text (ValueError naming the file and what is wrong)."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{where}: not TOML ({exc})") from None
    table = doc.get("declared") if isinstance(doc.get("declared"), dict) else doc
    declared_by = table.pop("declared_by", doc.get("declared_by", "")) if isinstance(table, dict) else ""
    values: dict[str, Any] = {}
    for key, value in table.items():
        if key == "declared" or key == "declared_by":
            continue
        if key not in BY_KEY:
            raise ValueError(f"{where}: unknown key {key!r}; known: {', '.join(BY_KEY)}")
        values[key] = _checked(BY_KEY[key], value, where)
    if not values:
        raise ValueError(f"{where}: declares nothing (see docs/DECLARED.md)")
    ordered = {item.key: values[item.key] for item in ITEMS if item.key in values}
    declaration = Declaration(where, ordered, str(declared_by))
    try:
        DEFAULT_PROFILE.replace(**declaration.profile_changes())
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return declaration


def read(path: Path) -> Declaration:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"--declared {path}: {getattr(exc, 'strerror', None) or exc}") from None
    return dataclasses.replace(parse(text, f"--declared {path}"), path=str(path), text=text)


def declared_profile(profile: Profile, declaration: Declaration) -> Profile:
    """``profile`` with the declared settings; ValueError when a flag set it to something else."""
    changes = declaration.profile_changes()
    for key, value in changes.items():
        given, default = getattr(profile, key), getattr(DEFAULT_PROFILE, key)
        given, default = getattr(given, "value", given), getattr(default, "value", default)
        if given != default and given != value:
            raise ValueError(f"--declared {declaration.path} declares {key} = {value!r} but the command line asks for "
                             f"{given!r}; drop one of them")
    return profile.replace(**changes)
