"""A box answering no NONE within time_out (diagnose/batching): silent, late, or holding answers back until several
are due, told apart by a lone NONE waited for past time_out and NONE requests sent together."""

from __future__ import annotations

from conformance.diagnose.batching import Measured, judge, title_of


def test_a_late_lone_answer_and_a_batch_answered_at_once_is_a_batch() -> None:
    m = Measured(6.0, 5.0, ((2, 0), (4, 0), (8, 8), (5, 0), (6, 0), (7, 0)))
    assert judge(m) == ("batch", 8)
    title = title_of("batch", m, 8)
    assert "until 8 are due" in title and "6.0 s" in title and "time_out (5.0 s)" in title and "T1" in title


def test_late_whatever_is_sent_together_is_a_late_box() -> None:
    m = Measured(5.6, 5.0, ((2, 0), (4, 0), (8, 0), (16, 0)))
    assert judge(m) == ("late", None)
    assert "only after 5.6 s" in title_of("late", m, None)


def test_silence_and_a_prompt_answer_say_nothing_new() -> None:
    assert judge(Measured(None, 5.0)) == ("silent", None)
    assert judge(Measured(0.01, 5.0)) == ("", None)
