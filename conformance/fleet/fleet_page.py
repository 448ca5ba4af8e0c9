"""fleet.html: one self-contained page, one row per box, each linking its own report.

Jinja2 with autoescape on (the same rules as report.html: every string passes
:func:`~conformance.report.summary.clean_text`, so whatever a box sent shows as text,
never as markup). Links are relative to the fleet directory and percent-encoded.
"""

from __future__ import annotations

import functools
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from urllib.parse import quote

import jinja2
from markupsafe import Markup

from .. import i18n
from ..model.verdicts import VERDICT_ORDER
from ..report.html import display_time, i18n_environment
from ..report.summary import atomic_write_bytes, clean_text, format_duration, one_line

#: the CSS class of each box status (the colours of report.html's overall line)
STATUS_CLASS = {"conforms": "ok", "expected failures": "ok", "fails": "bad", "error": "bad", "interrupted": "warn",
                "not run": "muted", "incomplete": "warn", "unjudged": "warn"}


#: each box status in words (the status itself stays English in fleet.json)
STATUS_NAMES = {"conforms": i18n.N_("conforms"), "expected failures": i18n.N_("expected failures"),
                "fails": i18n.N_("fails"), "error": i18n.N_("error"), "interrupted": i18n.N_("interrupted"),
                "not run": i18n.N_("not run"), "incomplete": i18n.N_("incomplete"), "unjudged": i18n.N_("unjudged")}


def _finalize(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, str) and not isinstance(value, Markup):
        return clean_text(value)
    return value


def _href(path: str | None) -> str:
    return quote(path, safe="/") if path else ""


@functools.cache
def environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("conformance.fleet", "templates"),
        autoescape=True, finalize=_finalize, trim_blocks=True, lstrip_blocks=True,
        undefined=jinja2.StrictUndefined, extensions=["jinja2.ext.i18n"],
    )
    i18n_environment(env)
    env.filters["href"] = _href
    env.filters["one_line"] = one_line
    return env


def render_fleet_html(doc: dict[str, Any]) -> str:
    boxes = []
    for box in doc["boxes"]:
        totals = box["totals"] or {}
        boxes.append({**box, "cls": STATUS_CLASS.get(box["status"], "warn"),
                      "duration": format_duration(box["duration_s"]) if box["duration_s"] is not None else "",
                      "counts": [(v.value, totals.get(v.value, 0)) for v in VERDICT_ORDER if totals.get(v.value)]})
    state = "ok" if doc["passed"] else ("warn" if not doc["complete"] else "bad")
    return environment().get_template("fleet.html.j2").render(
        doc=doc, boxes=boxes, state=state, duration=format_duration(doc["duration_s"]), started=display_time(doc["started"]),
        generated=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"), lang=i18n.current(),
        status_names={k: i18n.gettext(v) for k, v in STATUS_NAMES.items()},
    )


def write_fleet_html(path: Path, doc: dict[str, Any]) -> Path:
    return atomic_write_bytes(path, render_fleet_html(doc).encode("utf-8", "replace"))
