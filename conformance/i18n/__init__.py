"""The language of what a reader sees: ``--lang en|zh-CN``.

gettext message catalogues (``locale/<ll_CC>/LC_MESSAGES/isight.mo``, compiled from the
``.po`` files next to them, shipped in the package) read with the standard library's
:mod:`gettext`; Babel manages them (``python -m conformance.i18n.update``) but is not
needed at run time.

One language is active per process: :func:`activate` sets it, :func:`language` sets it
for a ``with`` block and restores the previous one. English (the msgids themselves) is
active until something chooses another. Every command takes ``--lang``
(:func:`add_lang_option`); its default comes from the locale (:func:`default_lang`).

Machine-read values (summary.json keys and values, verdict names in CI-facing places,
junit's properties) stay English; what people read is translated with :func:`gettext`
(``_``) and :func:`ngettext`. Strings defined at import time are marked with :func:`N_`
and translated where they are shown.
"""

from __future__ import annotations

import argparse
import contextlib
import gettext as _gettext
import os
import re
import unicodedata
from collections.abc import Callable, Iterator, Mapping, Sequence
from importlib import resources
from typing import Any

DOMAIN = "isight"
LANGS = ("en", "zh-CN")
DEFAULT = "en"
#: --lang value -> gettext locale directory name
LOCALE_DIRS = {"en": "en", "zh-CN": "zh_CN"}

_catalogues: dict[str, _gettext.NullTranslations] = {}
_active: list[str] = [DEFAULT]


def catalogue(lang: str) -> _gettext.NullTranslations:
    """The translations of ``lang`` (a NullTranslations for English), read once."""
    if lang not in _catalogues:
        if lang == DEFAULT:
            _catalogues[lang] = _gettext.NullTranslations()
        else:
            mo = resources.files(__name__) / "locale" / LOCALE_DIRS[lang] / "LC_MESSAGES" / f"{DOMAIN}.mo"
            with mo.open("rb") as fh:
                _catalogues[lang] = _gettext.GNUTranslations(fh)
    return _catalogues[lang]


def normalise(lang: str | None) -> str | None:
    """``zh-CN``, ``zh_CN``, ``zh_CN.UTF-8``, ``zh`` -> ``zh-CN``; ``en*``, ``C``, ``POSIX`` -> ``en``;
    None for an empty value, ValueError for a language without a catalogue."""
    if not lang:
        return None
    code = lang.split(".", 1)[0].split("@", 1)[0].replace("_", "-").lower()
    if code.startswith("zh"):
        return "zh-CN"
    if code in ("c", "posix") or code.startswith("en"):
        return "en"
    raise ValueError(f"--lang: {lang!r} is not one of {', '.join(LANGS)}")


def default_lang(environ: Mapping[str, str] | None = None) -> str:
    """The language the locale asks for: the first of LC_ALL, LC_MESSAGES, LANG that is set
    (the POSIX order); zh-CN when it starts with ``zh``, else English."""
    env = os.environ if environ is None else environ
    for name in ("LC_ALL", "LC_MESSAGES", "LANG"):
        value = env.get(name)
        if value:
            return "zh-CN" if value.lower().startswith("zh") else DEFAULT
    return DEFAULT


def current() -> str:
    """The active language (``en`` or ``zh-CN``)."""
    return _active[0]


def activate(lang: str | None) -> str:
    """Make ``lang`` the active language (None: :func:`default_lang`); returns it."""
    chosen = normalise(lang) or default_lang()
    catalogue(chosen)  # a missing catalogue fails here, not in the middle of a report
    _active[0] = chosen
    return chosen


@contextlib.contextmanager
def language(lang: str | None) -> Iterator[str]:
    """``with language("zh-CN"):`` activates a language for the block and restores the previous one."""
    before = _active[0]
    try:
        yield activate(lang)
    finally:
        _active[0] = before


def gettext(message: str) -> str:
    """``message`` in the active language (itself when the catalogue has no translation)."""
    return catalogue(_active[0]).gettext(message)


def ngettext(singular: str, plural: str, n: int) -> str:
    return catalogue(_active[0]).ngettext(singular, plural, n)


_ = gettext


def N_(message: str) -> str:
    """Marks a string for extraction without translating it (for import-time constants)."""
    return message


#: the Chinese name shown beside each verdict (PASS, FAIL ... stay as they are: CI greps them)
VERDICT_NAMES = {
    "PASS": N_("PASS"), "FAIL": N_("FAIL"), "NON-STRICT": N_("NON-STRICT"), "INFORMATIONAL": N_("INFORMATIONAL"),
    "INCONCLUSIVE": N_("INCONCLUSIVE"), "SKIP": N_("SKIP"), "ERROR": N_("ERROR"),
}
#: the requirement levels (GB/T 1.1's words in Chinese, the RFC 2119 keyword beside them)
LEVEL_NAMES = {"MUST": N_("MUST"), "SHOULD": N_("SHOULD"), "MAY": N_("MAY")}


def beside(word: str, names: Mapping[str, str] = VERDICT_NAMES) -> str:
    """``FAIL`` in English; ``FAIL 不通过`` in another language: the token CI greps, its word beside it.
    A combination like ``MUST/SHOULD`` is translated part by part."""
    if "/" in word:
        return "/".join(beside(w, names) for w in word.split("/"))
    shown = gettext(names[word]) if word in names else word
    return word if shown == word else f"{word} {shown}"


def level_name(level: str) -> str:
    """``MUST`` in English; ``应 (MUST)`` in Chinese (GB/T 1.1's word, the RFC 2119 keyword beside it)."""
    parts = []
    for word in level.split("/"):
        shown = gettext(LEVEL_NAMES[word]) if word in LEVEL_NAMES else word
        parts.append(word if shown == word else f"{shown} ({word})")
    return "/".join(parts)


def add_lang_option(add: Callable[..., Any] | Any, flag: str = "--lang", dest: str = "lang") -> None:
    """Add ``--lang en|zh-CN`` to a parser (argparse's parser or group, or an ``add_argument``/
    ``addoption`` function). Its value is None when not given: :func:`activate` then reads the locale."""
    adder = getattr(add, "add_argument", add)
    adder(flag, dest=dest, default=None, metavar="|".join(LANGS), type=_lang_type,
          help=gettext("language of the reports and the terminal: en or zh-CN (default: from the locale, "
                       "LC_ALL/LC_MESSAGES/LANG starting 'zh' gives zh-CN)"))


def _lang_type(text: str) -> str:
    lang = normalise(text)
    if lang is None:
        raise ValueError("empty")
    return lang


def lang_in_argv(argv: Sequence[str]) -> str | None:
    """The ``--lang`` value in a command line, before the parser exists (its help text is translated)."""
    for i, arg in enumerate(argv):
        if arg == "--lang" and i + 1 < len(argv):
            return argv[i + 1]
        if arg.startswith("--lang="):
            return arg.split("=", 1)[1]
    return None


# -- text that fits a terminal whose Chinese characters take two columns -------------------------------
_WIDE = "\u2e80-\u9fff\uff00-\uffef\u3000-\u303f"
#: punctuation a line does not start with (closing) or end with (opening): it stays with its neighbour
_CLOSE, _OPEN = "，。、；：！？）】》」』〉", "（【《「『〈"
_TOKEN = re.compile(f"[{_OPEN}]*(?:[{_WIDE}]|[^\\s{_WIDE}]+)[{_CLOSE}]*|\\s+")


def cells(text: str) -> int:
    """Terminal columns of ``text``: a wide (Chinese) character takes two."""
    return sum(2 if unicodedata.east_asian_width(ch) in "WF" else 1 for ch in text)


def wrap_cells(text: str, width: int) -> list[str]:
    """``text`` in lines of at most ``width`` terminal columns, broken between words or between Chinese
    characters, never inside a word (a word longer than a line stays whole)."""
    lines: list[str] = []
    line, space = "", False
    for token in _TOKEN.findall(" ".join(text.split())):
        if token.isspace():
            space = bool(line)
            continue
        piece = (" " if space else "") + token
        if line and cells(line + piece) > width:
            lines.append(line)
            line = token
        else:
            line += piece
        space = False
    return [*lines, line] if line else lines


class HelpFormatter(argparse.HelpFormatter):
    """argparse's help, wrapped by terminal columns (argparse counts a Chinese character as one)."""

    def _split_lines(self, text: str, width: int) -> list[str]:
        return wrap_cells(text, width)

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return "\n".join(indent + line for line in wrap_cells(text, width - len(indent)))
