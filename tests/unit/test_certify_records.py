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
