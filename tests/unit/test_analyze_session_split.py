"""Sessions split by connection lifetimes and time, not by address alone (issue 26): a connection that stays
open while others come and go, or several robots behind one address, no longer make one endless session."""

from __future__ import annotations

from pathlib import Path

from conformance.analyze import AnalyzeConfig, analyze, build_cases
from conformance.analyze.sessions import SPLIT_AFTER_S, SPLIT_CONNECTIONS
from conformance.model.verdicts import Verdict
from conformance.protocol import Action, answer, encode, request
from tests.analyze_util import Capture, canonical, exchange

LOOSE = AnalyzeConfig(rate_tolerance=0.5, jitter_tolerance=3.0)
PING = (encode(request(Action.NONE)), encode(answer(Action.NONE)))


def _judged(cap: Capture, tmp_path: Path):  # type: ignore[no-untyped-def]
    a = analyze(cap.write(tmp_path / "s.pcapng"), LOOSE)
    return a, {c.id: c for c in build_cases(a)}


def test_sessions_under_a_connection_that_stays_open_are_split_by_count(tmp_path: Path) -> None:
    cap = Capture()
    long = cap.tcp(30000)
    exchange(long, *PING)
    n = SPLIT_CONNECTIONS // 2 + 2  # two connections each: past the bound
    for i in range(n):
        canonical(cap, poses=12, port=31000 + 2 * i)
    exchange(long, *PING)
    long.close()
    a, c = _judged(cap, tmp_path)
    assert a.ctx.stats.sessions >= 2  # one endless session before: every connection's outcome held to the end
    s1 = c["OBS-S1-robot"]
    inconclusive = [line for line in s1.observed.splitlines() if "continues session 1, split there" in line]
    assert inconclusive, s1.observed
    # one address, many command connections at once (the ping connection holds them together): the wire
    # cannot tell which robot's session a connection belongs to, so nothing is a robot's FAIL
    assert s1.verdict is Verdict.INCONCLUSIVE and "command connections from one address at once" in s1.observed
    assert c["OBS-S5-robot"].verdict is not Verdict.FAIL, c["OBS-S5-robot"].message


def test_a_session_older_than_the_bound_takes_no_new_connection(tmp_path: Path) -> None:
    cap = Capture()
    long = cap.tcp(30000)
    exchange(long, *PING)
    canonical(cap, poses=12, port=31000)
    cap.t += SPLIT_AFTER_S + 1
    exchange(long, *PING)
    canonical(cap, poses=12, port=32000)
    long.close()
    a, _c = _judged(cap, tmp_path)
    assert a.ctx.stats.sessions == 2
