"""``report.html`` of a soak: the verdicts, the findings, and the plots over time (one file, no CDN)."""

from __future__ import annotations

from html import escape
from pathlib import Path
from typing import Any

from ..report.summary import atomic_write_bytes, format_duration
from .judge import RESOURCE_FLOORS, RESOURCE_NAMES
from .plots import latency_plot, resource_plot, sessions_plot

CSS = """body{font-family:DejaVu Sans,Helvetica,Arial,sans-serif;margin:2em;max-width:60em;color:#222}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:.3em .6em;text-align:left;vertical-align:top}
.FAIL{color:#c62828;font-weight:bold}.PASS{color:#2e7d32}.INFORMATIONAL,.INCONCLUSIVE{color:#b26a00}
figure{margin:1em 0}small{color:#555}"""


def _trend(doc: dict[str, Any], key: str, series: str) -> dict[str, Any] | None:
    return next((t for t in doc.get(key, []) if t["series"] == series), None)


def render(doc: dict[str, Any]) -> str:
    rows = doc["windows"]
    totals = doc["totals"]
    state = "complete" if doc["complete"] else ("running" if not doc["final"] else f"cut short ({doc['ended_by']})")
    parts = [f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>Soak: {escape(doc['target'])}</title>"
             f"<style>{CSS}</style></head><body>",
             f"<h1>Soak of {escape(doc['target'])}: {escape(doc['overall'])}</h1>",
             f"<p>{format_duration(doc['elapsed_s'])} ({state}), {totals['sessions']:,} sessions "
             f"({totals['served']:,} served, {totals['failed']:,} failed), {len(rows)} windows of "
             f"{doc['settings']['window_s']:g} s, {doc['settings']['robots']} robot(s), {escape(str(doc.get('session', '')))} "
             f"sessions of {doc['settings']['cycle_s']:g} s, planted events {escape(doc['settings']['events'])}: "
             f"{escape(', '.join(f'{k} × {n}' for k, n in totals['events'].items()) or 'none')}.</p>",
             "<h2>Verdicts</h2><table><tr><th>clause</th><th>verdict</th><th>what the soak saw</th></tr>"]
    for v in doc["verdicts"]:
        parts.append(f"<tr><td>{escape(v['clause'])}</td><td class='{escape(v['verdict'])}'>{escape(v['verdict'])}</td>"
                     f"<td>{escape(v['message'])}</td></tr>")
    parts.append("</table>")
    if doc["findings"]:
        parts.append("<h2>Findings</h2><ul>" + "".join(f"<li>{escape(f)}</li>" for f in doc["findings"]) + "</ul>")
    if doc.get("notes"):
        parts.append("<h2>What happened</h2><ul>" + "".join(f"<li>{escape(n)}</li>" for n in doc["notes"][:200])
                     + "</ul>")
    if doc.get("box_last_words"):
        words = doc["box_last_words"]
        parts.append(f"<p>{escape(words['summary'])}</p><pre>{escape(words['tail'])}</pre>")
    if doc.get("stopped"):
        s = doc["stopped"]
        parts.append(f"<p class='FAIL'>The box stopped serving after {s['after_sessions']:,} sessions "
                     f"({format_duration(s['at_s'])} in): {escape(s['reason'])}</p>")
    parts.append("<h2>Over time</h2>")
    if rows:
        parts.append(f"<figure>{latency_plot(rows, _trend(doc, 'latency_trends', 'latency p50'), doc['profile']['time_out_ms'])}"
                     "<figcaption><small>Per window: the p50, p99 and max of the time from a pose's send to its "
                     "answer; dashed, the Theil–Sen line of the p50. Red bands: windows with failed sessions or "
                     "missing answers; ticks at the bottom: planted events.</small></figcaption></figure>")
        parts.append(f"<figure>{sessions_plot(rows)}</figure>")
        for key, (unit, _abs, _rel) in RESOURCE_FLOORS.items():
            if any(r["resources"].get(key) is not None for r in rows):
                parts.append(f"<figure>{resource_plot(rows, key, 'Box: ' + RESOURCE_NAMES[key], unit, _trend(doc, 'resource_trends', key))}</figure>")
        if any(r["resources"].get("soak_rss_mb") is not None for r in rows):
            parts.append(f"<figure>{resource_plot(rows, 'soak_rss_mb', 'The soak itself: RSS', 'MB', None)}</figure>")
    half = doc.get("half_open") or {}
    parts.append(f"<h2>Robots that vanished</h2><p>{half.get('abandoned', 0)} connections abandoned without FIN or RST; "
                 f"the box closed {half.get('freed_by_box', 0)} of them itself"
                 + (f" (median after {half['freed_after_s_median']:.1f} s)" if half.get("freed_after_s_median") else "")
                 + f"; the rest were reset by the soak after {half.get('hold_s', 0):g} s, as a rebooted robot's "
                 "stack answers the box's next segment.</p>")
    pcaps = doc.get("pcaps")
    if pcaps:
        if pcaps.get("error"):
            parts.append(f"<p>No pcaps: {escape(pcaps['error'])}</p>")
        else:
            links = [f"<a href='pcaps/{escape(n)}'>{escape(n)}</a>" for n in [*pcaps["findings"], *pcaps["recent"]]]
            parts.append(f"<h2>Pcaps</h2><p>{len(pcaps['findings'])} window(s) with findings kept, the newest "
                         f"{pcaps['keep']} window(s) kept, {pcaps['deleted']} older ones deleted: "
                         + (", ".join(links) or "none") + "</p>")
    parts.append(_window_table(rows))
    parts.append(f"<p><small>{escape(doc.get('command', ''))}</small></p></body></html>")
    return "".join(parts)


def _window_table(rows: list[dict[str, Any]]) -> str:
    out = ["<h2>Windows</h2><table><tr><th>#</th><th>from</th><th>served</th><th>failed</th><th>p50 ms</th>"
           "<th>p99 ms</th><th>max ms</th><th>missing</th><th>events</th><th>box RSS MB</th><th>fds</th></tr>"]
    shown = rows if len(rows) <= 200 else [r for r in rows if r["sessions_failed"] or r["answers_missing"]] + rows[-20:]
    for r in shown:
        lat, res = r["latency"], r["resources"]
        out.append("<tr>" + "".join(f"<td>{escape(str(c))}</td>" for c in (
            r["index"], format_duration(r["start_s"]), r["sessions_ok"], r["sessions_failed"], lat.get("p50"),
            lat.get("p99"), lat.get("max"), r["answers_missing"],
            ", ".join(f"{k} × {n}" for k, n in r["events"].items()), res.get("rss_mb", ""), res.get("fds", ""))) + "</tr>")
    out.append("</table>")
    return "".join(out)


def write_page(doc: dict[str, Any], path: Path) -> None:
    atomic_write_bytes(path, render(doc).encode("utf-8"))


__all__ = ["render", "write_page"]
