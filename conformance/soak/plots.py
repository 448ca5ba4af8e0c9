"""SVG plots of a soak over time (self-contained: no script, no external reference).

* :func:`latency_plot`: each window's pose-answer p50, p99 and max, the Theil–Sen line of the p50,
  and time_out when it is near the data;
* :func:`resource_plot`: one resource of the box per plot, with its Theil–Sen line;
* events and failing windows are drawn as ticks along the bottom (events) and red bands (failures).

The x axis is the soak's elapsed time; the y axis starts at 0 so a growth shows as a slope.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any
from xml.sax.saxutils import escape

FONT = "DejaVu Sans, Helvetica, Arial, sans-serif"
W, H = 720, 220
ML, MR, MT, MB = 56, 110, 28, 30
COLOURS = {"p50": "#2e7d32", "p99": "#b26a00", "max": "#1565c0", "fit": "#6a1b9a", "value": "#1565c0"}
EVENT_COLOURS = {"vanish": "#6a1b9a", "reset": "#c62828", "stall": "#b26a00", "burst": "#00838f"}


def _nice(top: float) -> float:
    if top <= 0 or not math.isfinite(top):
        return 1.0
    power = 10 ** math.floor(math.log10(top))
    for m in (1, 2, 2.5, 5, 10):
        if m * power >= top:
            return m * power
    return 10 * power


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def _frame(title: str, unit: str, x_end: float, y_top: float) -> tuple[list[str], Any, Any]:
    pw, ph = W - ML - MR, H - MT - MB

    def sx(x: float) -> float:
        return ML + pw * (x / x_end if x_end else 0)

    def sy(y: float) -> float:
        return MT + ph * (1 - min(max(y, 0.0), y_top) / y_top)

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" '
           f'font-family="{FONT}" role="img"><title>{escape(title)}</title>',
           f'<text x="{ML}" y="16" font-size="12" font-weight="bold">{escape(title)}</text>',
           f'<rect x="{ML}" y="{MT}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>']
    for i in range(5):
        y = y_top * i / 4
        out.append(f'<line x1="{ML}" x2="{ML + pw}" y1="{sy(y):.1f}" y2="{sy(y):.1f}" stroke="#e3e3e3"/>')
        out.append(f'<text x="{ML - 4}" y="{sy(y) + 3:.1f}" font-size="10" text-anchor="end">{_fmt(y)}</text>')
    for i in range(5):
        x = x_end * i / 4
        out.append(f'<text x="{sx(x):.1f}" y="{H - 10}" font-size="10" text-anchor="middle">{_clock(x)}</text>')
    out.append(f'<text x="12" y="{MT + ph / 2:.0f}" font-size="10" transform="rotate(-90 12 {MT + ph / 2:.0f})" '
               f'text-anchor="middle">{escape(unit)}</text>')
    return out, sx, sy


def _clock(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _line(points: Sequence[tuple[float, float | None]], sx: Any, sy: Any, colour: str, dash: str = "") -> str:
    coords = " ".join(f"{sx(x):.1f},{sy(y):.1f}" for x, y in points if y is not None and math.isfinite(y))
    extra = f' stroke-dasharray="{dash}"' if dash else ""
    return f'<polyline points="{coords}" fill="none" stroke="{colour}" stroke-width="1.5"{extra}/>' if coords else ""


def _marks(rows: Sequence[dict[str, Any]], sx: Any) -> list[str]:
    out = []
    bottom = H - MB
    for row in rows:
        if row.get("sessions_failed") or row.get("answers_missing"):
            x0, x1 = sx(row["start_s"]), sx(row["end_s"])
            out.append(f'<rect x="{x0:.1f}" y="{MT}" width="{max(1.0, x1 - x0):.1f}" height="{bottom - MT}" '
                       f'fill="#c62828" fill-opacity="0.12"><title>window {row["index"]}: '
                       f'{row.get("sessions_failed", 0)} failed, {row.get("answers_missing", 0)} missing</title></rect>')
        for kind, n in (row.get("events") or {}).items():
            x = sx((row["start_s"] + row["end_s"]) / 2)
            out.append(f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{bottom - 8}" y2="{bottom}" '
                       f'stroke="{EVENT_COLOURS.get(kind, "#444")}" stroke-width="2"><title>{escape(kind)} × {n}, '
                       f'window {row["index"]}</title></line>')
    return out


def _legend(labels: Sequence[tuple[str, str]]) -> list[str]:
    out = []
    for i, (label, colour) in enumerate(labels):
        y = MT + 12 + 14 * i
        out.append(f'<rect x="{W - MR + 8}" y="{y - 8}" width="10" height="3" fill="{colour}"/>'
                   f'<text x="{W - MR + 22}" y="{y - 4}" font-size="10">{escape(label)}</text>')
    return out


def _fit_points(fit: dict[str, Any] | None, x0: float, x1: float) -> list[tuple[float, float | None]]:
    if not fit:
        return []
    return [(x, fit["intercept"] + fit["slope"] * x / 3600) for x in (x0, x1)]


def latency_plot(rows: Sequence[dict[str, Any]], trend: dict[str, Any] | None, time_out_ms: float) -> str:
    mids = [(r["start_s"] + r["end_s"]) / 2 for r in rows]
    x_end = rows[-1]["end_s"] if rows else 1.0
    p99s = sorted(r["latency"]["p99"] for r in rows if r["latency"].get("p99") is not None)
    # the scale follows the p99s (their 90th percentile, with room): a max far above is drawn on the top edge
    top = _nice(1.5 * p99s[int(0.9 * (len(p99s) - 1))]) if p99s else 1.0
    top = min(top, _nice(time_out_ms * 1.1))
    clipped = sum(1 for r in rows if (r["latency"].get("max") or 0) > top)
    title = "Answer latency per window (pose stream)" + (f"; {clipped} max above the scale, on its top edge"
                                                         if clipped else "")
    out, sx, sy = _frame(title, "ms", x_end, top)
    out += _marks(rows, sx)
    for q in ("max", "p99", "p50"):
        out.append(_line([(x, r["latency"].get(q)) for x, r in zip(mids, rows)], sx, sy, COLOURS[q]))
    fit = (trend or {}).get("per_hour")
    out.append(_line(_fit_points(fit, mids[0] if mids else 0, x_end), sx, sy, COLOURS["fit"], "5 3"))
    if time_out_ms <= top:
        out.append(f'<line x1="{ML}" x2="{W - MR}" y1="{sy(time_out_ms):.1f}" y2="{sy(time_out_ms):.1f}" '
                   'stroke="#c62828" stroke-dasharray="2 2"/>')
    out += _legend([("max", COLOURS["max"]), ("p99", COLOURS["p99"]), ("p50", COLOURS["p50"]),
                    ("p50 trend", COLOURS["fit"])])
    out.append("</svg>")
    return "".join(out)


def resource_plot(rows: Sequence[dict[str, Any]], key: str, title: str, unit: str,
                  trend: dict[str, Any] | None) -> str:
    mids = [(r["start_s"] + r["end_s"]) / 2 for r in rows]
    x_end = rows[-1]["end_s"] if rows else 1.0
    ys = [r.get("resources", {}).get(key) for r in rows]
    top = _nice(max((y for y in ys if y is not None), default=1.0) * 1.1)
    out, sx, sy = _frame(title, unit, x_end, top)
    out += _marks(rows, sx)
    out.append(_line(list(zip(mids, ys)), sx, sy, COLOURS["value"]))
    out.append(_line(_fit_points((trend or {}).get("per_hour"), mids[0] if mids else 0, x_end), sx, sy,
                     COLOURS["fit"], "5 3"))
    out += _legend([(key, COLOURS["value"]), ("trend", COLOURS["fit"])])
    out.append("</svg>")
    return "".join(out)


def sessions_plot(rows: Sequence[dict[str, Any]]) -> str:
    x_end = rows[-1]["end_s"] if rows else 1.0
    mids = [(r["start_s"] + r["end_s"]) / 2 for r in rows]
    top = _nice(max((r["sessions_ok"] + r["sessions_failed"] for r in rows), default=1) * 1.1)
    out, sx, sy = _frame("Sessions per window, and planted events", "sessions", x_end, top)
    out += _marks(rows, sx)
    out.append(_line([(x, r["sessions_ok"]) for x, r in zip(mids, rows)], sx, sy, COLOURS["p50"]))
    out.append(_line([(x, r["sessions_failed"]) for x, r in zip(mids, rows)], sx, sy, "#c62828"))
    out += _legend([("served", COLOURS["p50"]), ("failed", "#c62828"),
                    *((k, c) for k, c in EVENT_COLOURS.items())])
    out.append("</svg>")
    return "".join(out)


__all__ = ["latency_plot", "resource_plot", "sessions_plot"]
