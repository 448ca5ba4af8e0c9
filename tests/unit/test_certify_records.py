"""certify-robot's settings and records."""

from __future__ import annotations

import pytest

from conformance.certify.records import INJECTIONS, CertifyConfig, monotonic_wall
from conformance.protocol import Action, Profile, ResultCode
from tests.unit.test_observed_session import Fake


def test_defaults_are_safe():
    cfg = CertifyConfig()
    assert (cfg.host, cfg.port, cfg.sessions, cfg.wait_s) == ("127.0.0.1", 9004, 1, 120.0)
    assert cfg.slow_delay_s == 0.0 and not cfg.extension


@pytest.mark.parametrize("changes", [
    {"inject": ("explode",)}, {"port": 70000}, {"sessions": 0}, {"wait_s": 0}, {"linger_s": -1},
    {"rate_tolerance": 1.5}, {"jitter_tolerance": 0}, {"max_session_s": 10**6},
])
def test_bad_settings_are_value_errors(changes):
    with pytest.raises(ValueError):
        CertifyConfig(**changes)


def test_box_config_follows_the_injections():
    cfg = CertifyConfig(inject=("not-ready", "busy", "slow"), profile=Profile(time_out_ms=2000))
    box = cfg.box_config()
    assert box.not_ready and box.vision_result == ResultCode.BUSY and box.extension
    assert cfg.slow_delay_s == pytest.approx(1.6)
    plain = CertifyConfig().box_config()
    assert not plain.not_ready and plain.vision_result == ResultCode.OK
    assert set(INJECTIONS) == {"not-ready", "slow", "busy", "close-mid-cycle"}


def test_roles():
    fake = Fake()
    silent, stream, cmd = fake.conn(0.0), fake.conn(0.1), fake.conn(0.2)
    stream.actions += [Action.POSE, Action.POSE]
    cmd.actions += [Action.POSE, Action.CYCLE_ON]
    assert (silent.role, stream.role, cmd.role) == ("unknown", "stream", "command")
    assert stream.open and "stream, tcp from 127.0.0.1:" in stream.label
    assert fake.session.tcp == [silent, stream, cmd]


def test_the_clock_reads_like_wall_time_and_never_goes_back():
    import time

    clock = monotonic_wall()
    first = clock()
    assert abs(first - time.time()) < 1.0
    values = [clock() for _ in range(1000)]
    assert values == sorted(values) and values[0] >= first


# -- the answer latencies: a box takes time to start and stop a detection ------------------------------
def test_latency_defaults_to_a_few_hundred_ms_inside_time_out():
    from conformance.certify.latency import default_range_ms

    assert CertifyConfig().latency_range_ms == (100.0, 400.0)
    lo, hi = CertifyConfig(profile=Profile(time_out_ms=300, vision_time_out_ms=5000)).latency_range_ms
    assert 0 < lo <= hi < 300  # scaled down below a short time_out
    assert default_range_ms(Profile(time_out_ms=5000, vision_time_out_ms=500))[1] < 500


@pytest.mark.parametrize(("text", "expected"), [("100-400", (100.0, 400.0)), ("0", (0.0, 0.0)), ("250", (250.0, 250.0)),
                                                 ("0.5-1.5", (0.5, 1.5))])
def test_parse_latency(text, expected):
    from conformance.certify.latency import parse_latency

    assert parse_latency(text) == expected


@pytest.mark.parametrize("text", ["", "a-b", "400-100", "1-2-3", "-5", "100-"])
def test_parse_latency_rejects(text):
    from conformance.certify.latency import parse_latency

    with pytest.raises(ValueError, match="--answer-latency"):
        parse_latency(text)


def test_a_latency_at_or_above_time_out_is_refused():
    with pytest.raises(ValueError, match="below time_out"):
        CertifyConfig(answer_latency_ms=(100.0, 1000.0), profile=Profile(time_out_ms=1000))
    with pytest.raises(ValueError, match="below time_out"):  # the result request waits vision_time_out
        CertifyConfig(answer_latency_ms=(100.0, 900.0), profile=Profile(time_out_ms=5000, vision_time_out_ms=800))
    CertifyConfig(answer_latency_ms=(0.0, 0.0))


def test_latencies_are_seeded_and_only_for_cycle_on_off_and_the_result_request():
    draws = [CertifyConfig(seed=7).answer_latency() for _ in range(2)]
    actions = [Action.CYCLE_ON, Action.POSE, Action.CYCLE_OFF, Action.NONE, Action.VISION_RESULT, Action.PROG_IDX, None]
    first, second = ([d.delay_s(a) for a in actions] for d in draws)
    assert first == second  # the same seed, the same latencies
    assert [a for a, d in zip(actions, first) if d] == [Action.CYCLE_ON, Action.CYCLE_OFF, Action.VISION_RESULT]
    assert all(0.1 <= d <= 0.4 for d in first if d)
    assert [CertifyConfig(seed=8).answer_latency().delay_s(Action.CYCLE_ON) for _ in range(2)][0] != first[0]
    assert CertifyConfig(answer_latency_ms=(0.0, 0.0)).answer_latency().delay_s(Action.CYCLE_ON) == 0.0
    slow = CertifyConfig(inject=("slow",), profile=Profile(time_out_ms=2000)).answer_latency()
    assert slow.delay_s(Action.CYCLE_ON) == 0.0  # --inject slow holds every answer itself
    assert "--inject slow" in CertifyConfig(inject=("slow",), profile=Profile(time_out_ms=2000)).latency_text()
    assert "100–400 ms" in CertifyConfig().latency_text()
    assert "--seed 7" in draws[0].describe() and "at once" in CertifyConfig(answer_latency_ms=(0, 0)).answer_latency().describe()
