"""The soak's verdicts from windows (issue 38): flat passes with its coverage, growth beyond noise fails T2,
a growing resource is a finding with its slope, a stop is S5/R5 with N; windows and pages from rows."""

from __future__ import annotations

import random

from conformance.model.exit_codes import EXIT_CONNECTION, EXIT_MISBEHAVED, EXIT_NOT_READY, EXIT_OK, EXIT_TIMEOUT
from conformance.model.verdicts import Verdict
from conformance.soak.document import overall
from conformance.soak.page import render
from conformance.soak.sessions import EXIT_PLANTED, classify
from conformance.soak.verdicts import Stopped, judge_soak
from conformance.soak.windows import SessionOutcome, Window, WindowRow


def rows(n: int = 30, latency=lambda i, rng: 0.4 + rng.gauss(0, 0.03), rss=lambda i, rng: 30 + rng.gauss(0, 0.05),
         fds=lambda i, rng: 9.0, failed=lambda i: 0, per_window: int = 20, seed: int = 1) -> list[WindowRow]:
    rng = random.Random(seed)
    out, total = [], 0
    for i in range(n):
        window = Window(i, i * 60.0, 5000)
        for _ in range(per_window):
            base = latency(i, rng)
            window.add(SessionOutcome(0, True, poses_sent=50, poses_answered=50,
                                      pose_latencies_ms=[max(0.01, base + rng.gauss(0, 0.02)) for _ in range(50)]))
        for _ in range(failed(i)):
            window.add(SessionOutcome(0, False, "connect", "connection refused by 127.0.0.1:9 (cmd connection)"))
        row = window.close((i + 1) * 60.0, total, {"rss_mb": rss(i, rng), "fds": fds(i, rng)}, 0.0)
        total = row.sessions_total
        out.append(row)
    return out


def by_clause(judged) -> dict[str, object]:
    return {v.clause: v for v in judged.verdicts}


def test_a_flat_box_passes_and_says_what_the_verdict_covers():
    judged = judge_soak(rows(), None)
    verdicts = by_clause(judged)
    assert {v.verdict for v in verdicts.values()} == {Verdict.PASS}
    assert "flat over 30 min 00 s, 600 sessions, 30 windows" in verdicts["T2"].message
    assert not judged.findings and overall(judged) == "PASS"


def test_latency_growing_beyond_noise_fails_t2_with_slope_and_windows():
    judged = judge_soak(rows(latency=lambda i, rng: 0.4 + 0.3 * i + rng.gauss(0, 0.03)), None)
    t2 = by_clause(judged)["T2"]
    assert t2.verdict is Verdict.FAIL and t2.windows and t2.windows[-1] == 29
    p50 = judged.latency[0]
    assert p50.grows and 14 <= p50.per_hour.slope <= 22  # 0.3 ms a minute: 18 ms per hour
    assert "per 1,000 sessions (95 % CI" in t2.message and overall(judged) == "FAIL"


def test_latency_that_grows_by_less_than_its_floor_is_not_a_backlog():
    judged = judge_soak(rows(latency=lambda i, rng: 0.4 + 0.002 * i + rng.gauss(0, 0.001)), None)
    assert by_clause(judged)["T2"].verdict is Verdict.PASS  # significant, but 0.06 ms over the soak


def test_one_wild_window_does_not_make_a_trend():
    judged = judge_soak(rows(latency=lambda i, rng: 40.0 if i == 25 else 0.4 + rng.gauss(0, 0.03)), None)
    assert by_clause(judged)["T2"].verdict is Verdict.PASS


def test_a_growing_resource_is_a_finding_with_its_slope_per_1000_sessions():
    judged = judge_soak(rows(rss=lambda i, rng: 30 + 0.062 * i + rng.gauss(0, 0.01)), None)  # 3.1 MB per 1,000
    assert len(judged.findings) == 1
    finding = judged.findings[0]
    assert finding.startswith("RSS +3.1 MB per 1,000 sessions (95 % CI "), finding
    assert by_clause(judged)["R5"].verdict is Verdict.INFORMATIONAL and overall(judged) == "PASS with findings"


def test_a_step_in_descriptors_during_warm_up_is_not_a_finding():
    judged = judge_soak(rows(fds=lambda i, rng: 9.0 if i == 0 else 14.0), None)
    assert not judged.findings


def test_a_box_that_stopped_fails_s5_with_n_or_r5_when_abandoned_connections_held_it():
    data = rows(failed=lambda i: 3 if i >= 27 else 0)
    judged = judge_soak(data, Stopped(540, 1620.0, "connect", "connection refused by 127.0.0.1:9 (cmd connection)"))
    s5 = by_clause(judged)["S5"]
    assert s5.verdict is Verdict.FAIL and "stopped serving after 540 sessions (27 min 00 s into the soak)" in s5.message
    # abandoned connections open when it stopped prove nothing by themselves: still S5, with the figure
    judged = judge_soak(data, Stopped(540, 1620.0, "closed", "the box closed it", half_open=64))
    s5 = by_clause(judged)["S5"]
    assert s5.verdict is Verdict.FAIL and "with 64 connections of vanished robots still open" in s5.message
    # the rebooted robot refused: R5
    judged = judge_soak(data, Stopped(540, 1620.0, "after-vanish", "connection refused", half_open=2))
    assert by_clause(judged)["R5"].verdict is Verdict.FAIL
    # served again once the soak reset them: they held it, R5 with N
    judged = judge_soak(rows(), None, held=[Stopped(540, 1620.0, "closed", "the box closed it", half_open=64)])
    r5 = by_clause(judged)["R5"]
    assert r5.verdict is Verdict.FAIL and r5.message.startswith("the box stopped serving after 540 sessions")
    assert "with 64 connections of vanished robots open, and served again once the soak reset them" in r5.message


def test_too_few_windows_is_inconclusive_for_trends():
    judged = judge_soak(rows(n=4), None)
    assert by_clause(judged)["T2"].verdict is Verdict.INCONCLUSIVE and not judged.resources


def test_windows_count_sessions_events_and_what_is_missing():
    window = Window(0, 0.0, 100.0)
    window.add(SessionOutcome(0, True, poses_sent=10, poses_answered=10, pose_latencies_ms=[1.0] * 9 + [150.0],
                              late=1))
    window.add(SessionOutcome(1, True, event="vanish", poses_sent=10, poses_answered=4))  # abandoned on purpose
    window.add(SessionOutcome(0, False, "timeout", "no answer", poses_sent=10, poses_answered=7))
    window.add(SessionOutcome(0, False, "not-ready", "0001"))
    window.note_event("vanish")
    row = WindowRow.from_dict(window.close(60.0, 100, {}, 3.0).to_dict())
    assert (row.sessions_ok, row.sessions_failed, row.sessions_cut, row.sessions_not_ready) == (1, 1, 1, 1)
    assert row.sessions_total == 102 and row.answers_missing == 3 and row.answers_late == 1
    assert row.failures == {"timeout": 1} and row.events == {"vanish": 1} and row.latency["max"] == 150.0


def test_classify_names_what_ended_a_session():
    assert classify(EXIT_OK, "", "") == "" and classify(EXIT_PLANTED, "", "") == ""
    assert classify(EXIT_NOT_READY, "", "") == "not-ready"
    assert classify(EXIT_MISBEHAVED, "", "") == "misbehaved"
    assert classify(EXIT_CONNECTION, "connect", "") == "connect"
    assert classify(EXIT_TIMEOUT, "command-starved", "") == "command-starved"
    assert classify(EXIT_TIMEOUT, "", "") == "timeout" and classify(EXIT_CONNECTION, "", "") == "closed"
    assert classify(EXIT_CONNECTION, "connect", "vanish") == "after-vanish"


def test_the_page_draws_every_plot_inline():
    data = rows(rss=lambda i, rng: 30 + 0.062 * i)
    judged = judge_soak(data, None)
    doc = {"target": "box <1>", "overall": overall(judged), "complete": True, "final": True, "ended_by": "duration",
           "elapsed_s": 1800.0, "totals": {"sessions": 600, "served": 600, "failed": 0, "events": {"stall": 2}},
           "settings": {"window_s": 60, "robots": 1, "cycle_s": 5, "events": "6/h"}, "session": "S1",
           "profile": {"time_out_ms": 5000}, "half_open": {}, "command": "soak", "stopped": None,
           **judged.to_dict(), "windows": [r.to_dict() for r in data]}
    page = render(doc)
    assert page.count("<svg") == 4 and "box &lt;1&gt;" in page and "RSS +3.1 MB per 1,000 sessions" in page
    assert "<script" not in page and "http://" not in page.replace("http://www.w3.org/2000/svg", "")


def test_a_box_warming_up_is_not_a_finding():
    # RSS climbs fast in the first windows, then levels off: significant, but not sustained
    judged = judge_soak(rows(rss=lambda i, rng: 30 + 4 * (1 - 0.6 ** i) + rng.gauss(0, 0.01)), None)
    rss = next(t for t in judged.resources if t.series == "rss_mb")
    assert not rss.grows and rss.later_per_hour < (rss.per_hour.slope if rss.per_hour else 0) / 3
    assert not judged.findings


def test_a_soak_that_judged_no_session_is_inconclusive():
    data = [Window(i, i * 60.0, 5000) for i in range(8)]
    for window in data:
        window.add(SessionOutcome(0, False, "not-ready", "ProgIdx answered 409"))
    judged = judge_soak([w.close(w.start_s + 60, 0, {}, 0.0) for w in data], None)
    assert {v.verdict for v in judged.verdicts} == {Verdict.INCONCLUSIVE}
    assert "8 ended not ready" in judged.verdicts[0].message and overall(judged) == "INCONCLUSIVE"


def test_several_robots_may_find_the_boxes_cycle_ended_by_another():
    from conformance.endpoints.robot.robot_steps import STEP_TABLE
    from conformance.protocol import Action, answer
    from conformance.soak.sessions import _shared_cycle_off

    judge = STEP_TABLE["cycle_off"].judge
    assert judge is not None
    idle = answer(Action.CYCLE_OFF, 0x0002)
    assert judge(idle, 1).code != EXIT_OK  # one robot: CycleOff must be 0000 (S1)
    shared = _shared_cycle_off(judge)(idle, 1)
    assert shared.code == EXIT_OK and "another robot" in shared.reason
    assert _shared_cycle_off(judge)(answer(Action.CYCLE_OFF, 0x1001), 1).code != EXIT_OK


def test_a_tail_that_grows_alone_is_a_finding_not_a_t2_fail():
    def tail(i: int, rng: random.Random) -> float:
        return 0.4 + rng.gauss(0, 0.02)

    data = rows(latency=tail)
    for i, row in enumerate(data):  # the p99 climbs 1 ms a window, the median stays where it was
        row.latency["p99"] = 2.0 + 1.0 * i
    judged = judge_soak(data, None)
    t2 = by_clause(judged)["T2"]
    assert t2.verdict is Verdict.PASS and "the tail grows" in t2.message
    assert any(f.startswith("tail latency p99 +") for f in judged.findings)
    assert by_clause(judged)["R5"].verdict is Verdict.PASS  # a latency finding is not a resource's
