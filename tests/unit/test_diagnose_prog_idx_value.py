"""The ProgIdx value echoed (diagnose/prog_idx_value): the one reading of the int32 that maps every value sent to
the value echoed, named; none when the echo is right or no reading fits."""

from __future__ import annotations

from conformance.diagnose.prog_idx_value import READINGS, VALUES, reading, title


def test_each_reading_is_told_from_the_others_by_the_values_sent() -> None:
    for name, echo in READINGS:
        pairs = [(v, echo(v)) for v in VALUES]
        assert reading(pairs) == name, name


def test_a_right_echo_a_conflict_and_an_unknown_echo_name_nothing() -> None:
    assert reading([(v, v) for v in VALUES]) == ""
    assert reading([(v, 409) for v in VALUES]) == ""  # 409 (not ready) says nothing about the reading
    assert reading([(7, 7), (70000, 12345)]) == ""


def test_the_title_names_the_bytes_read_and_the_values_seen() -> None:
    pairs = [(v, v & 0xFFFF) for v in VALUES]
    text = title(reading(pairs), pairs)
    assert text.startswith("Echoes only the low two bytes of the ProgIdx int32 (read unsigned)")
    assert "65536 comes back as 0" in text and "7, 255 echoed right" in text and "E1/E2" in text
