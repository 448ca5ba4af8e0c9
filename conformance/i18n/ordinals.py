"""Ordinal numbers in the language of the run: 1st 2nd 3rd 4th 11th 12th 13th 21st; 第1 第41.

English takes "st"/"nd"/"rd" after a last digit 1/2/3, except in 11, 12 and 13 (and 111,
112, 113 ...), which take "th" like every other number. Chinese writes 第 before the number
and a measure word after it (第41块: the 41st block).
"""

from __future__ import annotations

from . import current

_SUFFIX = {1: "st", 2: "nd", 3: "rd"}


def english_ordinal(n: int) -> str:
    """``n`` as an English ordinal: 1st, 2nd, 3rd, 4th, 11th, 12th, 13th, 21st, 101st, 111th."""
    if n % 100 in (11, 12, 13):
        return f"{n}th"
    return f"{n}{_SUFFIX.get(n % 10, 'th')}"


def ordinal(n: int, lang: str | None = None) -> str:
    """``n`` as an ordinal in ``lang`` (default: the active language): "41st"; "第41"."""
    if (lang or current()) == "zh-CN":
        return f"第{n}"
    return english_ordinal(n)


def nth_block(n: int, lang: str | None = None) -> str:
    """The ``n``-th block: "the 41st block"; "第41块"."""
    if (lang or current()) == "zh-CN":
        return f"第{n}块"
    return f"the {english_ordinal(n)} block"
