"""The settings of an analysis (conformance/analyze/analysis_context.py)."""

from __future__ import annotations

import pytest

from conformance.analyze.analysis_context import AnalyzeConfig, Context
from conformance.protocol import Profile, TcpCheckPolicy


@pytest.mark.parametrize("kwargs, words", [
    ({"ports": ()}, "--port"), ({"ports": (0,)}, "--port"), ({"rate_tolerance": 1.5}, "rate tolerance"),
    ({"jitter_tolerance": 0}, "jitter tolerance"), ({"linger_s": -1}, "--linger"),
])
def test_bad_settings_are_one_clear_value_error(kwargs, words):
    with pytest.raises(ValueError, match=words):
        AnalyzeConfig(**kwargs)


def test_frames_are_judged_as_a_sender_must_send_them():
    ctx = Context(AnalyzeConfig(profile=Profile(tcp_check=TcpCheckPolicy.IGNORE, time_out_ms=250)))
    assert ctx.judged.tcp_check is TcpCheckPolicy.ZERO  # F6: a TCP sender MUST send 00 00
    assert ctx.time_out_s == 0.25
    assert [ctx.label(), ctx.label()] == [1, 2]
