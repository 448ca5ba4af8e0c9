"""A small self-contained SVG of answer latencies (no script, no external reference).

Presentation decisions:

* linear scale from 0 ms, so a growing backlog (T2) shows as a slope;
* huge outliers do not flatten the plot: when the maximum is above 3 × p99 the scale
  stops there and every point above it is drawn on the top edge with a red ▲ marker
  (and counted in the header line);
* ``time_out`` is drawn when it is near the data (within 2 × the scale); otherwise the
  header says it is off scale, and how far the maximum is below it;
* a request whose latency is not finite (NaN/inf: no answer) is counted and marked ×;
* more points than 2 per pixel column are reduced to the min and max of each column,
  which keeps every spike visible and the SVG small (≈ 15 KB for 50,000 points).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from xml.sax.saxutils import escape

from ..model.percentiles import percentile
from .summary import clean_text

FONT = "DejaVu Sans, Helvetica, Arial, sans-serif"
C_DATA, C_P50, C_P99, C_LIMIT, C_AXIS, C_GRID = "#1565c0", "#2e7d32", "#b26a00", "#c62828", "#444", "#e3e3e3"
ML, MR, MT, MB = 48, 100, 38, 30  # margins: left (y labels), right (line labels), top (title + notes), bottom
CLIP_FACTOR = 3.0  # scale stops at CLIP_FACTOR × p99 when the maximum is beyond it
DOTS_UP_TO = 150  # draw a dot per point up to this many points


def fmt_ms(value: float) -> str:
    """A latency for a label: 3 significant figures, no exponent."""
    if value == 0:
        return "0"
    if value < 10:
        return f"{value:.2f}".rstrip("0").rstrip(".") if value >= 0.01 else f"{value:.3g}"
    if value < 100:
        return f"{value:.1f}".rstrip("0").rstrip(".")
    return f"{value:,.0f}"


def _nice_step(raw: float) -> float:
    """The smallest 1, 2, 2.5 or 5 × 10^k that is >= raw."""
    if raw <= 0:
        return 1.0
    power = 10 ** math.floor(math.log10(raw))
    for m in (1, 2, 2.5, 5, 10):
        if m * power >= raw * (1 - 1e-9):
            return m * power
    return 10 * power


def _f(x: float) -> str:
    return f"{x:.1f}".rstrip("0").rstrip(".")


def _text(x: float, y: float, body: str, anchor: str = "start", size: float = 10, fill: str = C_AXIS,
          extra: str = "") -> str:
    return (f'<text x="{_f(x)}" y="{_f(y)}" text-anchor="{anchor}" font-size="{size}" fill="{fill}"{extra}>'
            f"{escape(clean_text(body))}</text>")


def _spread(labels: list[tuple[float, str, str]], top: float, bottom: float, gap: float = 11) -> list[tuple[float, str, str]]:
    """Move label baselines apart (at least ``gap``), keeping them within [top, bottom]."""
    labels = sorted(labels)
    for i in range(1, len(labels)):
        if labels[i][0] - labels[i - 1][0] < gap:
            labels[i] = (labels[i - 1][0] + gap, *labels[i][1:])
    overflow = labels[-1][0] - bottom if labels else 0
    if overflow > 0:
        labels = [(y - overflow, c, t) for y, c, t in labels]
    return [(max(y, top), c, t) for y, c, t in labels]


def _open(width: int, height: int, title: str, css: str) -> tuple[int, int, int, int, list[str]]:
    """The SVG document's opening (size clamped, background, title): width, height, plot width/height, lines."""
    width, height = max(int(width), ML + MR + 40), max(int(height), MT + MB + 40)
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'viewBox="0 0 {width} {height}" role="img" font-family="{FONT}" class="{css}">',
        f"<title>{escape(clean_text(title))}</title>",
        f'<rect x="0" y="0" width="{width}" height="{height}" fill="#fff"/>',
        _text(ML, 15, title, size=11, fill="#111", extra=' font-weight="bold"'),
    ]
    return width, height, width - ML - MR, height - MT - MB, out


def _empty(out: list[str], pw: int, ph: int, message: str) -> str:
    """Close an SVG that has no data: an empty plot frame with ``message`` in it."""
    out.append(f'<rect x="{ML}" y="{MT}" width="{pw}" height="{ph}" fill="none" stroke="{C_GRID}"/>')
    out.append(_text(ML + pw / 2, MT + ph / 2 + 4, message, anchor="middle", size=11, fill="#777"))
    out.append("</svg>")
    return "\n".join(out)


def _hline(y: float, pw: int, stroke: str, extra: str = "") -> str:
    return f'<line x1="{ML}" y1="{_f(y)}" x2="{ML + pw}" y2="{_f(y)}" stroke="{stroke}"{extra}/>'


def _y_label(ph: int, label: str) -> str:
    return _text(12, MT + ph / 2, label, anchor="middle", extra=f' transform="rotate(-90 12 {_f(MT + ph / 2)})"')


def _axis_lines(pw: int, ph: int) -> list[str]:
    return [f'<line x1="{ML}" y1="{MT + ph}" x2="{ML + pw}" y2="{MT + ph}" stroke="{C_AXIS}"/>',
            f'<line x1="{ML}" y1="{MT}" x2="{ML}" y2="{MT + ph}" stroke="{C_AXIS}"/>']


def _x_tick(x: float, ph: int, label: str) -> list[str]:
    return [f'<line x1="{_f(x)}" y1="{MT + ph}" x2="{_f(x)}" y2="{MT + ph + 3}" stroke="{C_AXIS}"/>',
            _text(x, MT + ph + 13, label, anchor="middle")]


def _latency_scale(p99: float, hi: float, time_out_ms: float | None) -> tuple[float, float, float | None]:
    """(y step, top of the y axis, time_out when it is drawn on that scale)."""
    y_max = CLIP_FACTOR * p99 if p99 > 0 and hi > CLIP_FACTOR * p99 else hi
    limit = float(time_out_ms) if time_out_ms and time_out_ms <= 2 * max(y_max, 1e-9) else None
    y_max = max(y_max, limit or 0.0) or 1.0
    step = _nice_step(y_max / 4)
    return step, math.ceil(y_max / step - 1e-9) * step, limit


class _Points:
    """The latency line's points, in pixels: every point, or min and max per pixel column, with the
    columns of points above the scale (``clipped``) and of requests never answered (``lost``)."""

    def __init__(self, latencies_ms: Sequence[float], pw: int, y_top: float,
                 xx: Callable[[int], float], yy: Callable[[float], float]) -> None:
        self.points: list[tuple[float, float]] = []
        self.clipped: list[float] = []
        self.lost: list[float] = []
        if len(latencies_ms) <= 2 * pw:
            self._every(latencies_ms, y_top, xx, yy)
        else:
            self._columns(latencies_ms, pw, y_top, yy)

    def _every(self, latencies_ms: Sequence[float], y_top: float, xx: Callable[[int], float],
               yy: Callable[[float], float]) -> None:
        for i, v in enumerate(latencies_ms):
            if not math.isfinite(v):
                self.lost.append(xx(i))
                continue
            v = max(0.0, float(v))
            self.points.append((xx(i), yy(v)))
            if v > y_top:
                self.clipped.append(xx(i))

    def _columns(self, latencies_ms: Sequence[float], pw: int, y_top: float, yy: Callable[[float], float]) -> None:
        n = len(latencies_ms)
        cols: dict[int, list[float]] = {}
        for i, v in enumerate(latencies_ms):
            c = i * pw // n
            if not math.isfinite(v):
                if not self.lost or self.lost[-1] != ML + c:
                    self.lost.append(ML + c)
                continue
            v = max(0.0, float(v))
            col = cols.get(c)
            if col is None:
                cols[c] = [v, v, i, i]  # min, max, index of min, index of max
            elif v < col[0]:
                col[0], col[2] = v, i
            elif v > col[1]:
                col[1], col[3] = v, i
        for c, (lo, top, i_lo, i_top) in sorted(cols.items()):
            pair = [(i_lo, lo), (i_top, top)] if i_lo <= i_top else [(i_top, top), (i_lo, lo)]
            self.points.extend((ML + c + 0.5, yy(v)) for _, v in pair)
            if top > y_top:
                self.clipped.append(ML + c + 0.5)

    def svg(self, ph: int) -> list[str]:
        out = []
        if len(self.points) > 1:
            pts = " ".join(f"{_f(x)},{_f(y)}" for x, y in self.points)
            out.append(f'<polyline points="{pts}" fill="none" stroke="{C_DATA}" stroke-width="1" stroke-linejoin="round"/>')
        if len(self.points) <= DOTS_UP_TO:
            out.append(f'<g fill="{C_DATA}">' + "".join(f'<circle cx="{_f(x)}" cy="{_f(y)}" r="2"/>'
                                                        for x, y in self.points) + "</g>")
        if self.clipped:
            path = "".join(f"M{_f(x)},{MT - 1}l3.5,6h-7z" for x in self.clipped)
            out.append(f'<path d="{path}" fill="{C_LIMIT}"/>')
        if self.lost:
            path = "".join(f"M{_f(x - 3)},{MT + ph - 6}l6,6m0,-6l-6,6" for x in self.lost)
            out.append(f'<path d="{path}" stroke="{C_LIMIT}" stroke-width="1.2" fill="none"/>')
        return out


def latency_svg(latencies_ms: Sequence[float], title: str, time_out_ms: float | None = None,
                width: int = 640, height: int = 200) -> str:
    """The latency of each request (in request order) as an SVG document string."""
    width, height, pw, ph, out = _open(width, height, title, "latency")
    n = len(latencies_ms)
    finite = [max(0.0, float(v)) for v in latencies_ms if math.isfinite(v)]
    lost = n - len(finite)
    if not finite:
        return _empty(out, pw, ph, "no latency samples" if n == 0 else f"no answer to any of {n} requests")
    ordered = sorted(finite)
    p50, p99, hi = percentile(ordered, 50), percentile(ordered, 99), ordered[-1]
    step, y_top, limit = _latency_scale(p99, hi, time_out_ms)

    def yy(v: float) -> float:
        return MT + ph - min(v, y_top) / y_top * ph

    def xx(i: int) -> float:
        return ML + (i / (n - 1) * pw if n > 1 else pw / 2)

    for t in [k * step for k in range(int(round(y_top / step)) + 1)]:  # grid and y axis
        out += [_hline(yy(t), pw, C_GRID), _text(ML - 4, yy(t) + 3.5, fmt_ms(t), anchor="end")]
    out += [_y_label(ph, "latency (ms)"), *_axis_lines(pw, ph)]
    xstep = max(1, int(_nice_step(n / 6)))  # x axis: request numbers
    for r in [1, *range(xstep, n + 1, xstep)] if n > 1 else [1]:
        if r == 1 or xx(r - 1) - xx(0) >= 24:
            out += _x_tick(xx(r - 1), ph, f"{r:,}")
    out.append(_text(ML + pw, height - 3, "request #", anchor="end", fill="#777"))
    points = _Points(latencies_ms, pw, y_top, xx, yy)
    out += points.svg(ph)
    # reference lines, labelled on the right
    labels = [(yy(p50) + 3.5, C_P50, f"p50 {fmt_ms(p50)} ms"), (yy(p99) + 3.5, C_P99, f"p99 {fmt_ms(p99)} ms")]
    out += [_hline(yy(p50), pw, C_P50, ' stroke-dasharray="5 3"'), _hline(yy(p99), pw, C_P99, ' stroke-dasharray="5 3"')]
    if limit is not None:
        out.append(_hline(yy(limit), pw, C_LIMIT, ' stroke-width="1.5"'))
        labels.append((yy(limit) + 3.5, C_LIMIT, f"time_out {fmt_ms(limit)} ms"))
    out += [_text(ML + pw + 5, y, label, fill=colour) for y, colour, label in _spread(labels, MT + 4, MT + ph + 3)]
    # header line: what the reader must know that the lines do not show
    notes = [f"n={n:,}", f"max {fmt_ms(hi)} ms"]
    if points.clipped:
        notes.append(f"▲ {sum(v > y_top for v in finite):,} above {fmt_ms(y_top)} ms")
    if lost:
        notes.append(f"× {lost:,} no answer")
    if time_out_ms and limit is None:
        notes.append(f"time_out {fmt_ms(float(time_out_ms))} ms off scale")
    return _close(out, notes)


def _close(out: list[str], notes: list[str]) -> str:
    """The header line of notes, and the end of the document."""
    out.append(_text(ML, 29, " · ".join(notes), size=9.5, fill="#555"))
    out.append("</svg>")
    return "\n".join(out)


def _bin(values: Sequence[float], bins: int, width_bin: float, x_top: float) -> tuple[list[int], int]:
    """(count per bin, values beyond ``x_top``): those beyond the last bin are counted in it."""
    counts = [0] * bins
    over = 0
    for v in values:
        i = int(v / width_bin)
        if i >= bins:
            over += v > x_top
            i = bins - 1
        counts[i] += 1
    return counts, over


def histogram_svg(values_ms: Sequence[float], bins: int, title: str, expected_ms: float | None = None,
                  width: int = 640, height: int = 200) -> str:
    """A histogram of intervals (e.g. a pose stream's send intervals) as an SVG document string.

    The x axis starts at 0 and reaches at least twice ``expected_ms`` (drawn as a line), so
    a stream on its period shows as one bar on the line, a bursty one as bars at 0 and at a
    multiple of the period. Outliers beyond 3 × p99 are counted in the last bar (marked ▲).
    """
    width, height, pw, ph, out = _open(width, height, title, "histogram")
    bins = max(1, min(int(bins), pw))
    finite = sorted(max(0.0, float(v)) for v in values_ms if math.isfinite(v))
    if not finite:
        return _empty(out, pw, ph, "no interval samples")
    p50, p99, hi = percentile(finite, 50), percentile(finite, 99), finite[-1]
    top = CLIP_FACTOR * p99 if p99 > 0 and hi > CLIP_FACTOR * p99 else hi
    if expected_ms and expected_ms > 0:
        top = max(top, 2 * float(expected_ms))
    step = _nice_step((top or 1.0) / 5)
    x_top = max(step, math.ceil(top / step - 1e-9) * step)
    width_bin = x_top / bins
    counts, over = _bin(finite, bins, width_bin, x_top)
    c_max = max(counts)

    def xx(v: float) -> float:
        return ML + min(v, x_top) / x_top * pw

    def yy(c: float) -> float:
        return MT + ph - c / c_max * ph

    c_step = max(1, int(_nice_step(c_max / 4)))
    for c in range(0, c_max + 1, c_step):
        out += [_hline(yy(c), pw, C_GRID), _text(ML - 4, yy(c) + 3.5, f"{c:,}", anchor="end")]
    out.append(_y_label(ph, "count"))
    bars = []
    for i, c in enumerate(counts):
        if c:
            x0, x1 = xx(i * width_bin), xx((i + 1) * width_bin)
            bars.append(f'<rect x="{_f(x0 + 0.5)}" y="{_f(yy(c))}" width="{_f(max(0.8, x1 - x0 - 1))}" '
                        f'height="{_f(MT + ph - yy(c))}"/>')
    out.append(f'<g fill="{C_DATA}">' + "".join(bars) + "</g>")
    if over:
        out.append(f'<path d="M{_f(ML + pw - 4)},{MT - 1}l3.5,6h-7z" fill="{C_LIMIT}"/>')
    out += _axis_lines(pw, ph)
    for k in range(int(round(x_top / step)) + 1):
        out += _x_tick(xx(k * step), ph, fmt_ms(k * step))
    out.append(_text(ML + pw, height - 3, "interval (ms)", anchor="end", fill="#777"))
    labels = [(MT + 12, C_P50, f"p50 {fmt_ms(p50)} ms"), (MT + 24, C_P99, f"p99 {fmt_ms(p99)} ms")]
    if expected_ms and expected_ms > 0:
        x_exp = xx(float(expected_ms))
        out.append(f'<line x1="{_f(x_exp)}" y1="{MT}" x2="{_f(x_exp)}" y2="{MT + ph}" stroke="{C_LIMIT}" '
                   'stroke-width="1.5" stroke-dasharray="5 3"/>')
        labels.append((MT + 36, C_LIMIT, f"expected {fmt_ms(float(expected_ms))} ms"))
    for y, colour, label in labels:
        out.append(_text(ML + pw + 5, y, label, fill=colour))
    notes = [f"n={len(finite):,}", f"{bins} bins of {fmt_ms(width_bin)} ms", f"max {fmt_ms(hi)} ms"]
    if over:
        notes.append(f"▲ {over:,} above {fmt_ms(x_top)} ms in the last bin")
    if len(finite) < len(values_ms):
        notes.append(f"{len(values_ms) - len(finite):,} not finite")
    return _close(out, notes)
