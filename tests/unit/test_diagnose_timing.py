"""The timing judgements (pure): late vs stall vs silence, latency's slope over the block count, a request budget
per connection vs box-wide, and the titles they give."""

from __future__ import annotations

from conformance.diagnose import timing_judge as J
from conformance.diagnose.hypotheses import KINDS, Status
from conformance.diagnose.timing import third_count
from conformance.protocol import Action

CYCLE_ON = int(Action.CYCLE_ON)
POSE = int(Action.POSE)


def _statuses(stories: list[J.Story]) -> dict[str, Status]:
    return {k: s for k, s, _ in stories}


def test_a_late_answer_with_the_other_connection_answered_at_once_is_a_late_answer_of_that_action() -> None:
    kind, d, stories = J.late_story(J.LateFacts(CYCLE_ON, 5.0, 15.0, 5.5, 0.004, 0.2))
    assert kind == J.LATE
    assert _statuses(stories) == {J.LATE: Status.CONFIRMED, J.STALL: Status.RULED_OUT}
    title = J.title_of(kind, d)
    assert "CycleOn" in title and "time_out" in title and "5.5 s" in title and "4 ms" in title
    assert not title.startswith("unconfirmed")


def test_a_late_answer_with_the_other_connection_kept_waiting_is_a_stall_of_the_box() -> None:
    kind, d, stories = J.late_story(J.LateFacts(CYCLE_ON, 5.0, 15.0, 6.0, 5.7, 0.2))
    assert kind == J.STALL
    assert _statuses(stories)[J.LATE] is Status.RULED_OUT
    title = J.title_of(kind, d)
    assert "Stalls" in title and "CycleOn" in title and "6.0 s" in title


def test_the_other_connection_unanswered_is_a_stall_too() -> None:
    assert J.late_story(J.LateFacts(CYCLE_ON, 5.0, 15.0, 6.0, None, 0.2))[0] == J.STALL


def test_no_answer_past_time_out_or_an_answer_in_time_confirms_no_timing_story() -> None:
    silent = J.late_story(J.LateFacts(CYCLE_ON, 5.0, 15.0, None, None, 0.2))  # the other connection unanswered too
    in_time = J.late_story(J.LateFacts(CYCLE_ON, 5.0, 15.0, 0.01, None, 0.0))
    for kind, _, stories in (silent, in_time):
        assert kind == ""
        assert set(_statuses(stories).values()) == {Status.RULED_OUT}
    assert "3.0 × time_out" in silent[2][0][2]


def test_no_answer_past_time_out_while_another_connection_is_served_is_a_missing_answer() -> None:
    kind, d, stories = J.late_story(J.LateFacts(0x27, 5.0, 10.0, None, 0.003, 0.2))
    assert kind == J.SILENT and _statuses(stories)[J.SILENT] is Status.CONFIRMED
    title = J.title_of(kind, d)
    assert title.startswith("Never answers result request (27): no answer within 10") and "A1/T1" in title


def test_latency_growing_on_one_line_gives_the_slope_and_the_count_past_time_out() -> None:
    points = [(1, 0.062), (8, 0.482), (42, 2.522)]
    slope = J.slope_of(points, 5.0)
    assert slope is not None
    assert abs(slope.per_block_s - 0.06) < 0.001
    assert slope.crossing == 84  # 0.002 + 84 * 0.06 = 5.042 s > 5 s; 83 blocks: 4.982 s
    title = J.per_block_title(POSE, slope, points, 5.0)
    assert "latency" in title.lower() and "block count" in title and "84 or more blocks" in title
    assert "60 ms per block" in title


def test_flat_or_scattered_latency_is_no_slope() -> None:
    assert J.slope_of([(1, 0.002), (8, 0.003), (42, 0.004)], 5.0) is None
    assert J.slope_of([(1, 0.002), (8, 0.9), (42, 0.95)], 5.0) is None  # a jump, not a line
    assert J.slope_of([(1, 0.002), (8, 0.5)], 5.0) is None  # two points cannot show a line


def test_a_slope_that_stays_within_time_out_at_255_blocks_names_no_count() -> None:
    slope = J.slope_of([(1, 0.01), (8, 0.08), (40, 0.4)], 5.0)
    assert slope is not None and slope.crossing is None
    assert "or more blocks" not in J.per_block_title(POSE, slope, [(1, 0.01)], 5.0)


def test_the_third_count_is_where_the_first_two_reach_half_of_time_out() -> None:
    assert third_count([(1, 0.06), (8, 0.48)], 5.0) == 41  # 0.06 + 40 * 0.06 = 2.46 s
    assert third_count([(1, 0.002), (8, 0.003)], 5.0) is None  # no growth: nothing to extrapolate
    assert third_count([(1, 0.5), (8, 3.0)], 5.0) == 4  # past half already: between the two


def test_a_count_per_connection_is_a_budget_only_when_a_fresh_connection_is_answered_and_the_count_repeats() -> None:
    kind, d, stories = J.budget_story(J.BudgetFacts(1000, 300, True, 300))
    assert kind == J.BUDGET and _statuses(stories)[J.BUDGET] is Status.CONFIRMED
    title = J.title_of(kind, d)
    assert "300th request" in title and "connection" in title and "301" in title
    assert J.budget_story(J.BudgetFacts(1000, 300, False, None))[0] == ""  # box-wide (or a death)
    assert J.budget_story(J.BudgetFacts(1000, 300, True, 120))[0] == ""  # not the same count again
    assert J.budget_story(J.BudgetFacts(1000, None, True, None))[0] == ""  # never silent


def test_every_timing_kind_is_ranked_among_the_mechanism_kinds() -> None:
    assert set(J.KINDS) <= set(KINDS)


def test_durations_are_written_in_ms_below_one_second() -> None:
    assert J.seconds(0.0624) == "62 ms" and J.seconds(5.53) == "5.5 s" and J.seconds(0.0001) == "< 1 ms"


def _stream(n: int, knee: int, per: float, base: float = 0.002) -> list[float]:
    return [base + max(0, i - knee) * per for i in range(1, n + 1)]


def test_latency_growing_with_the_request_index_gives_the_knee_and_the_rate() -> None:
    g = J.index_growth(_stream(160, 100, 0.001))
    assert g is not None
    assert abs(g.per_request_s - 0.001) < 0.0001 and abs(g.knee - 100) <= 2 and g.last == 160
    kind, stories = J.per_request_story(g, 0.002, 160)
    assert kind == J.PER_REQUEST and stories[0][1] is Status.CONFIRMED
    title = J.per_request_title(g, 0.002)
    assert "latency" in title.lower() and "grows" in title and "connection" in title and "request 160" in title


def test_flat_latency_or_a_slow_fresh_connection_is_no_per_connection_growth() -> None:
    assert J.index_growth([0.002] * 200) is None
    assert J.index_growth(_stream(40, 10, 0.01)) is None  # too few requests to judge
    g = J.index_growth(_stream(160, 100, 0.001))
    assert J.per_request_story(g, 0.058, 160)[0] == ""  # the fresh connection slow too: the box, not the connection
    assert J.per_request_story(None, 0.002, 1000)[1][0][1] is Status.RULED_OUT


def test_a_gentle_slope_read_over_a_wide_count_still_names_its_count_past_time_out() -> None:
    slope = J.slope_of([(1, 0.02), (8, 0.16), (64, 1.28)], 5.0)  # 20 ms a block: 251 blocks pass 5 s
    assert slope is not None and slope.crossing == 251


def test_a_late_answer_ranks_after_a_mechanism_in_the_answers_and_before_a_story_only_seen_again() -> None:
    from conformance.diagnose.phase import _ordered
    from conformance.model.verdicts import RootCause

    def cause(name: str, mechanism: str | None) -> RootCause:
        rc = RootCause(name, ("T1",), name, "", [name], kind="unanswered")
        rc.confirmed, rc.diagnosis = mechanism is not None, {"mechanism": mechanism}
        return rc

    done = _ordered([cause("again", "reproduces"), cause("late", J.LATE), cause("open", None),
                     cause("size", "byte-limit")], {})
    assert [c.title for c in done.causes] == ["size", "late", "again", "open"]


def test_an_action_protocol_md_does_not_define_is_not_timed() -> None:
    # a fuzz case's bytes may carry any action byte (03 here): there is no valid request of it to send
    from conformance.diagnose.timing import _actions
    from conformance.model.verdicts import RootCause

    cause = RootCause("RC1", ("T1",), "t", "e", [], kind="unanswered")
    assert _actions([cause], {"RC1": frozenset({0x03, 0x23, 0x00})}) == [0x00, 0x23]
