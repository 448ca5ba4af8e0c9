"""Ordinals in English and Chinese (conformance/i18n/ordinals.py)."""

from __future__ import annotations

import pytest

from conformance.i18n import language
from conformance.i18n.ordinals import english_ordinal, nth_block, ordinal


@pytest.mark.parametrize("n, text", [(1, "1st"), (2, "2nd"), (3, "3rd"), (4, "4th"), (11, "11th"), (12, "12th"),
                                     (13, "13th"), (21, "21st"), (22, "22nd"), (23, "23rd"), (41, "41st"),
                                     (101, "101st"), (111, "111th"), (112, "112th"), (113, "113th"), (128, "128th"),
                                     (0, "0th"), (255, "255th")])
def test_english_ordinals(n: int, text: str) -> None:
    assert english_ordinal(n) == text


def test_chinese_ordinals_put_di_before_the_number_and_a_measure_word_after() -> None:
    assert ordinal(41, "zh-CN") == "第41"
    assert nth_block(41, "zh-CN") == "第41块"
    assert nth_block(41, "en") == "the 41st block"


def test_the_active_language_is_the_default() -> None:
    with language("zh-CN"):
        assert nth_block(3) == "第3块"
    with language("en"):
        assert ordinal(3) == "3rd"
