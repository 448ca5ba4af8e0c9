"""The latency SVG: well-formed, self-contained, small, honest about what it hides."""

from __future__ import annotations

import math
import random
import statistics
import xml.etree.ElementTree as ET

import pytest

from conformance.report import latency_svg
from conformance.report.svg import ML, MR, fmt_ms, percentile

NS = "{http://www.w3.org/2000/svg}"


def _parse(svg: str) -> ET.Element:
    root = ET.fromstring(svg)
    assert root.tag == f"{NS}svg"
    assert "<script" not in svg and "href" not in svg and "url(" not in svg
    return root


def _texts(root: ET.Element) -> list[str]:
    return ["".join(t.itertext()) for t in root.iter(f"{NS}text")]


def _polyline_points(root: ET.Element) -> int:
    lines = list(root.iter(f"{NS}polyline"))
    return sum(len(pl.get("points").split()) for pl in lines)


def test_ordinary_series_has_axes_and_labelled_percentiles():
    data = [2.0 + (i % 10) * 0.1 for i in range(100)]
    root = _parse(latency_svg(data, "T2-01 latency", time_out_ms=5))
    texts = _texts(root)
    assert "T2-01 latency" in texts
    assert root.find(f"{NS}title").text == "T2-01 latency"
    ordered = sorted(data)
    assert f"p50 {fmt_ms(percentile(ordered, 50))} ms" in texts
    assert f"p99 {fmt_ms(percentile(ordered, 99))} ms" in texts
    assert "time_out 5 ms" in texts
    assert "latency (ms)" in texts and "request #" in texts
    assert _polyline_points(root) == 100
    assert len(list(root.iter(f"{NS}circle"))) == 100
    assert root.get("width") == "640" and root.get("height") == "200"


def test_empty_and_single_point():
    empty = _parse(latency_svg([], "nothing"))
    assert "no latency samples" in _texts(empty)
    one = _parse(latency_svg([3.2], "one"))
    assert len(list(one.iter(f"{NS}circle"))) == 1
    assert "p50 3.2 ms" in _texts(one)
    zeros = _parse(latency_svg([0.0, 0.0], "zeros"))
    assert "p50 0 ms" in _texts(zeros)


def test_huge_outlier_is_clipped_with_a_marker():
    data = [2.0 + (i % 5) * 0.1 for i in range(300)] + [1e6]
    root = _parse(latency_svg(data, "outlier", time_out_ms=5000))
    header = _texts(root)[-1]
    assert "max 1,000,000 ms" in header
    assert "▲ 1 above" in header
    assert "time_out 5,000 ms off scale" in header
    y_ticks = [float(t.text.replace(",", "")) for t in root.iter(f"{NS}text")
               if t.get("text-anchor") == "end" and float(t.get("x")) == ML - 4]
    assert y_ticks and max(y_ticks) < 20  # the scale follows the data, not the outlier
    assert any(p.get("fill") == "#c62828" for p in root.iter(f"{NS}path"))


def test_time_out_near_the_data_is_drawn():
    root = _parse(latency_svg([1000.0, 3000.0, 4000.0], "near", time_out_ms=5000))
    assert "time_out 5,000 ms" in _texts(root)
    assert "off scale" not in _texts(root)[-1]


def test_no_answer_is_counted_not_plotted():
    root = _parse(latency_svg([1.0, math.nan, 2.0, math.inf], "lost"))
    assert "× 2 no answer" in _texts(root)[-1]
    assert _polyline_points(root) == 2
    all_lost = _parse(latency_svg([math.nan] * 3, "all lost"))
    assert "no answer to any of 3 requests" in _texts(all_lost)


def test_fifty_thousand_points_are_downsampled_and_small():
    rng = random.Random(7)
    data = [2 + rng.random() + i / 20000 for i in range(50_000)]
    data[30_000] = 900.0
    svg = latency_svg(data, "50k")
    assert len(svg.encode()) < 100_000
    root = _parse(svg)
    assert _polyline_points(root) <= 2 * (640 - ML - MR)
    assert not list(root.iter(f"{NS}circle"))
    assert "▲ 1 above" in _texts(root)[-1]  # the spike survives downsampling


def test_title_is_escaped():
    svg = latency_svg([1.0], "<script>x</script> & \x00")
    root = _parse(svg)
    assert "<script>x</script> & \\x00" in _texts(root)


@pytest.mark.parametrize("n", [1, 2, 5, 100, 1001])
def test_percentile_matches_statistics(n):
    data = sorted(random.Random(n).random() * 100 for _ in range(n))
    if n > 1:
        q = statistics.quantiles(data, n=100, method="inclusive")
        assert percentile(data, 50) == pytest.approx(statistics.median(data))
        assert percentile(data, 99) == pytest.approx(q[98])
    else:
        assert percentile(data, 99) == data[0]
