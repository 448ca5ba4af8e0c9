"""The clause registry: every clause of docs/PROTOCOL.md as data.

``clauses.json`` (next to this module, shipped in the package) holds each clause's
ID, levels, short title, full text, the profile flags that touch it and where the
source document speaks to it. Everything that names a clause (the ``@case`` check,
the report's clause table, CATALOGUE.md, certify's catalogue, ``isight-conformance
clauses``) reads it from here. Read once, cached; no sockets or clocks.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from importlib import resources
from typing import Any

from .levels import Level

LEVELS = tuple(Level)  # strongest first
_FIELDS = ("id", "level", "levels", "title", "text", "flags", "source")
ZH = "zh-CN"  # the optional key of a clause's Chinese title and text: {"title": ..., "text": ...}


@dataclass(frozen=True)
class Clause:
    id: str
    level: Level  # the strongest level the clause states
    levels: tuple[Level, ...]  # every level it states, strongest first
    title: str  # short, for tables
    text: str  # the requirement in full sentences
    flags: tuple[str, ...]  # the profile (and suite) flags that touch it
    source: str  # where the source document speaks to it ("" or a note for a [decision])
    title_zh: str = ""  # the title in Chinese (the source document's words where it speaks)
    text_zh: str = ""  # the text in Chinese; where the source document speaks, quoted as written

    def words(self, lang: str = "en") -> tuple[str, str]:
        """(title, text) in ``lang`` ("en" or "zh-CN"); English where no translation exists."""
        if lang == ZH and self.title_zh and self.text_zh:
            return self.title_zh, self.text_zh
        return self.title, self.text


class RegistryError(ValueError):
    """clauses.json is malformed (a packaging or editing mistake, never user input)."""


def _clause(entry: Any, index: int) -> Clause:
    if not isinstance(entry, dict) or set(entry) - {ZH} != set(_FIELDS):
        raise RegistryError(f"clauses.json entry {index}: expected exactly the keys {', '.join(_FIELDS)} "
                            f"(and optionally {ZH})")
    zh = entry.get(ZH, {"title": "", "text": ""})
    if not isinstance(zh, dict) or set(zh) != {"title", "text"} or \
            not all(isinstance(v, str) for v in zh.values()):
        raise RegistryError(f"clauses.json entry {index}: {ZH} must be an object with a string title and text")
    for key in ("id", "level", "title", "text", "source"):
        if not isinstance(entry[key], str):
            raise RegistryError(f"clauses.json entry {index}: {key} must be a string")
    for key in ("levels", "flags"):
        if not isinstance(entry[key], list) or not all(isinstance(v, str) for v in entry[key]):
            raise RegistryError(f"clauses.json entry {index}: {key} must be a list of strings")
    words = [entry["level"], *entry["levels"]]
    if not entry["levels"] or any(w not in Level.__members__ for w in words):
        raise RegistryError(f"clause {entry['id']}: levels must be some of {', '.join(LEVELS)}")
    clause = Clause(entry["id"], Level(entry["level"]), tuple(Level(w) for w in entry["levels"]), entry["title"],
                    entry["text"], tuple(entry["flags"]), entry["source"], zh["title"], zh["text"])
    if list(clause.levels) != sorted(set(clause.levels), key=LEVELS.index):
        raise RegistryError(f"clause {clause.id}: levels must be distinct, strongest first")
    if clause.level != clause.levels[0]:
        raise RegistryError(f"clause {clause.id}: level must be the strongest of levels ({clause.levels[0]})")
    if not clause.title or not clause.text:
        raise RegistryError(f"clause {clause.id}: title and text must not be empty")
    if any(not f.startswith("--") for f in clause.flags):
        raise RegistryError(f"clause {clause.id}: flags are command-line flags ('--name')")
    return clause


@dataclass(frozen=True)
class Registry:
    version: str
    families: dict[str, str]  # family letter -> heading, in document order
    families_zh: dict[str, str]  # family letter -> heading in Chinese (may be empty)
    clauses: dict[str, Clause]  # by id, in document order


def parse_registry(text: str) -> Registry:
    """The registry from the JSON text; RegistryError if malformed."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RegistryError(f"clauses.json is not JSON: {exc}") from None
    if not isinstance(data, dict) or not isinstance(data.get("version"), str) or \
            not isinstance(data.get("clauses"), list) or not isinstance(data.get("families"), dict):
        raise RegistryError("clauses.json: expected an object with a string 'version', an object 'families' "
                            "and a list 'clauses'")
    families: dict[str, str] = data["families"]
    if not all(isinstance(k, str) and len(k) == 1 and isinstance(v, str) and v for k, v in families.items()):
        raise RegistryError("clauses.json: families maps one letter to a heading")
    order = list(families)
    out: dict[str, Clause] = {}
    for i, entry in enumerate(data["clauses"]):
        clause = _clause(entry, i)
        if len(clause.id) < 2 or clause.id[0] not in families or not clause.id[1:].isdigit():
            raise RegistryError(f"clause id {clause.id!r} is not a family letter ({''.join(order)}) and a number")
        if clause.id in out:
            raise RegistryError(f"clause {clause.id} appears twice")
        out[clause.id] = clause
    ids = list(out)
    if ids != sorted(ids, key=lambda c: (order.index(c[0]), int(c[1:]))):
        raise RegistryError(f"clauses.json: clauses must be in document order (families {''.join(order)}, by number)")
    if {c[0] for c in ids} != set(order):
        raise RegistryError("clauses.json: every family has clauses, and every clause a family")
    families_zh = data.get("families_zh", {})
    if not isinstance(families_zh, dict) or not set(families_zh) <= set(families) or \
            not all(isinstance(v, str) and v for v in families_zh.values()):
        raise RegistryError("clauses.json: families_zh maps family letters to headings")
    return Registry(data["version"], families, families_zh, out)


@functools.lru_cache(maxsize=1)
def _load() -> Registry:
    text = resources.files("conformance.protocol").joinpath("clauses.json").read_text(encoding="utf-8")
    return parse_registry(text)


REGISTRY_VERSION: str = _load().version


def families(lang: str = "en") -> dict[str, str]:
    """Clause family letter -> heading ("F" -> "Frame"), in document order; in Chinese with ``lang="zh-CN"``
    (English for a family without a Chinese heading)."""
    reg = _load()
    if lang == ZH:
        return {k: reg.families_zh.get(k, v) for k, v in reg.families.items()}
    return dict(reg.families)


def all_clauses() -> dict[str, Clause]:
    """Every clause by id, in document order F1..E5 (a fresh dict; the clauses are frozen)."""
    return dict(_load().clauses)


def clause(id: str) -> Clause:
    """The clause ``id``; KeyError for an unknown id."""
    return _load().clauses[id]


@functools.lru_cache(maxsize=1)
def clause_ids() -> frozenset[str]:
    return frozenset(_load().clauses)


def text_of(id: str) -> str:
    """The clause's full text, "" for an unknown id."""
    found = _load().clauses.get(id)
    return found.text if found else ""
