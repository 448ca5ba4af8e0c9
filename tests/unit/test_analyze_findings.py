"""Bounded findings and series (conformance/analyze/findings.py)."""

from __future__ import annotations

import math
from array import array

from conformance.analyze.findings import BOX, KEEP, Findings, Series, frames_text
from conformance.model.verdicts import Verdict


def test_frames_text():
    assert frames_text([]) == "no frame"
    assert frames_text([5, 5]) == "frame 5"
    assert frames_text([3, 1]) == "frames 1, 3"
    assert frames_text([4, 2, 3]) == "frames 2-4"
    assert frames_text(range(1, 40, 2)).endswith("…")


def test_findings_are_counted_all_and_kept_few():
    f = Findings()
    f.check("A1", BOX, 10)
    for i in range(KEEP + 5):
        f.add("A1", BOX, Verdict.INCONCLUSIVE, f"i{i}", (i,))
    f.add("A1", BOX, Verdict.FAIL, "bad", (99,), robot=b"\x01\x02", box=b"\xff")
    t = f.tally("A1", BOX)
    assert t.checked == 10 and t.counts == {Verdict.INCONCLUSIVE: KEEP + 5, Verdict.FAIL: 1}
    assert len(t.kept[Verdict.INCONCLUSIVE]) == KEEP
    assert t.worst() is Verdict.FAIL
    bad = t.kept[Verdict.FAIL][0]
    assert (bad.robot_hex, bad.box_hex, bad.line()) == ("01 02", "ff", "frame 99: bad")
    assert f.count("A1", BOX, Verdict.FAIL) == 1 and f.count("T1", BOX, Verdict.FAIL) == 0


def test_a_series_keeps_an_evenly_spaced_sample_and_every_spike():
    s = Series(cap=64)
    for i in range(10_000):
        s.add(1000.0 if i == 7777 else float(i % 10))
    assert s.n == 10_000 and s.max == 1000.0 and s.max_at == 7778
    assert len(s.sample) < 64 and s.mean == (sum(i % 10 for i in range(10_000)) - 7 + 1000) / 10_000
    values, per = s.plot_values()
    assert per > 1 and len(values) <= 64 and 1000.0 in values  # the spike survives the reduction
    assert s.percentile(50) <= 9


def test_a_short_series_plots_every_value():
    s = Series()
    for v in (3.0, 1.0, 2.0):
        s.add(v)
    assert s.plot_values() == ([3.0, 1.0, 2.0], 1)
    assert s.describe().startswith("n=3")
    assert math.isnan(Series().mean) and Series().describe() == "none"


def test_extend_keeps_the_same_sample_and_buckets_as_adding_one_by_one():
    a, b, c = Series(cap=32), Series(cap=32), Series(cap=32)
    values = [float((i * 7919) % 1000) for i in range(5000)]
    for v in values:
        a.add(v)
    for i in range(0, 5000, 37):
        b.extend(values[i : i + 37])
        c.extend(array("d", values[i : i + 37]), peaks=False)
    assert (a.n, a.max, a.max_at, a.total) == (b.n, b.max, b.max_at, b.total) == (c.n, c.max, c.max_at, c.total)
    assert a.sample == b.sample == c.sample
    assert a.plot_values() == b.plot_values()
