"""conformance/fuzz/second_look.py, its pure parts: when the campaign's death search ends with the box back on its own,
the silence is recorded as a stall of the whole box (reported once by FUZZ-01), never as a death."""

from __future__ import annotations

from conformance.fuzz import second_look
from conformance.harness.target import Target
from conformance.harness.transcript import Transcript
from conformance.protocol import Profile

WHERE = second_look.Where(Transcript("T"), Target("127.0.0.1", 1), Profile(), 5.0, 37)


def test_a_death_search_that_ends_with_the_box_back_on_its_own_is_a_stall() -> None:
    assert second_look.stall_not_death(WHERE, restarted=False, confirmed=False, back=True, last=bytes(20))
    [stall] = second_look.take(("127.0.0.1", 1))
    assert stall.at_least and stall.lasted_s == 5.0 and stall.example == 37 and stall.after.endswith("…")
    assert "stalled for at least 5.0 s" in stall.describe()
    assert second_look.take(("127.0.0.1", 1)) == []  # taken once


def test_a_restart_a_confirmed_killer_or_a_box_still_gone_is_a_death() -> None:
    assert not second_look.stall_not_death(WHERE, restarted=True, confirmed=False, back=True, last=b"")
    assert not second_look.stall_not_death(WHERE, restarted=False, confirmed=True, back=True, last=b"")
    assert not second_look.stall_not_death(WHERE, restarted=False, confirmed=False, back=False, last=b"")
    assert second_look.take(("127.0.0.1", 1)) == []
