"""The soak's options (issue 38): spans, event rates, settings, and the command's one-line errors."""

from __future__ import annotations

import pytest

from conformance.commands import build_parser, main
from conformance.commands.soak import settings_from
from conformance.soak.duration import format_span, parse_span
from conformance.soak.settings import EventPlan, EventRate, SoakSettings, default_window, parse_events, parse_kinds


@pytest.mark.parametrize(("text", "seconds"), [("30s", 30), ("2h", 7200), ("8h", 28800), ("90m", 5400),
                                               ("1h30m", 5400), ("45", 45), ("1.5h", 5400), ("10min", 600)])
def test_spans(text, seconds):
    assert parse_span(text) == seconds


@pytest.mark.parametrize("text", ["", "abc", "30x", "h", "-5s", "2h junk", "0s", "8d"])
def test_bad_spans_say_so_in_one_line(text):
    with pytest.raises(ValueError) as err:
        parse_span(text)
    assert "\n" not in str(err.value) and "--duration" in str(err.value)


def test_format_span_reads_back():
    for seconds in (30, 90, 3600, 7260, 28800):
        assert parse_span(format_span(seconds)) == seconds


@pytest.mark.parametrize(("text", "rate"), [("6/h", EventRate(per_s=6 / 3600)), ("1/min", EventRate(per_s=1 / 60)),
                                            ("0.1", EventRate(share=0.1)), ("off", EventRate())])
def test_event_rates(text, rate):
    assert parse_events(text) == rate


@pytest.mark.parametrize("text", ["fast", "3/week", "1.5", "-1/h"])
def test_bad_event_rates(text):
    with pytest.raises(ValueError, match="--events"):
        parse_events(text)


def test_event_kinds_take_turns_and_the_plan_is_the_seeds():
    assert parse_kinds("vanish,stall") == ("vanish", "stall")
    with pytest.raises(ValueError, match="known"):
        parse_kinds("vanish,explode")
    plan = EventPlan(EventRate(share=1.0), ("vanish", "reset"), seed=1)
    assert [plan.next(0) for _ in range(4)] == ["vanish", "reset", "vanish", "reset"]
    a = EventPlan(EventRate(per_s=1.0), ("stall",), seed=5)
    b = EventPlan(EventRate(per_s=1.0), ("stall",), seed=5)
    assert [a.next(t / 10) for t in range(100)] == [b.next(t / 10) for t in range(100)]
    assert 0 < sum(1 for t in range(1000) if EventPlan(EventRate(per_s=0.5), ("stall",), 2).next(t)) <= 1000


def test_settings_refuse_what_cannot_run():
    with pytest.raises(ValueError, match="--window"):
        SoakSettings(duration_s=30, window_s=60)
    with pytest.raises(ValueError, match="--robots"):
        SoakSettings(duration_s=30, window_s=1, robots=0)
    with pytest.raises(ValueError, match="one or the other"):
        SoakSettings(duration_s=30, window_s=1, box_pid=1, restart_cmd="x")


@pytest.mark.parametrize("argv", [["soak", "--duration", "soon"], ["soak", "--duration", "30s", "--window", "1h"],
                                  ["soak", "--duration", "2h", "--events", "often"],
                                  ["soak", "--duration", "8h", "--target", "127.0.0.1:99999"]])
def test_the_command_refuses_bad_input_in_one_line_with_exit_2(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("isight-conformance soak: ") and "\n" not in err and "Traceback" not in err


@pytest.mark.parametrize(("duration", "window"), [("30s", 3.0), ("2h", 60.0), ("8h", 60.0), ("5s", 1.0)])
def test_the_duration_reaches_the_settings_with_a_window_that_fits(duration, window):
    args = build_parser("soak").parse_args(["soak", "--duration", duration])
    settings = settings_from(args)
    assert settings.window_s == window == default_window(settings.duration_s)
    assert settings.duration_s == {"30s": 30, "2h": 7200, "8h": 28800, "5s": 5}[duration]
