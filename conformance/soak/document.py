"""``soak.json``: the whole soak as one document, rebuilt at every checkpoint from the player's state."""

from __future__ import annotations

import time
from typing import Any

from .duration import format_span
from .player import SoakPlayer
from .verdicts import Judged, judge_soak

FORMAT = "isight-soak/1"


def build_document(player: SoakPlayer, *, target: str, box: dict[str, Any] | None, extension: str,
                   started: str, command: str, final: bool) -> tuple[dict[str, Any], Judged]:
    settings = player.settings
    rows = list(player.rows)
    stopped = player.stopped()
    judged = judge_soak(rows, stopped, player.ghosts.to_dict(), player.half_open_outages)
    soak_rss = list(player.soak_rss)
    elapsed = rows[-1].end_s if rows else round(player.elapsed(), 3)
    doc: dict[str, Any] = {
        "format": FORMAT,
        "complete": final and player.ended_by in ("duration", "stopped serving", "box died"),
        "final": final,
        "ended_by": player.ended_by if final else "running",
        "started": started,
        "written": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "elapsed_s": round(elapsed, 3),
        "target": target,
        "box": box,
        "extension": extension,
        "command": command,
        "profile": settings.profile.to_dict(),
        "settings": {
            "duration": format_span(settings.duration_s), "duration_s": settings.duration_s,
            "window_s": settings.window_s, "robots": settings.robots, "cycle_s": settings.cycle_s,
            "events": str(settings.events), "event_kinds": list(settings.event_kinds), "stall_s": settings.stall_s,
            "burst_size": settings.burst_size, "ghost_hold_s": settings.ghost_hold_s, "seed": settings.seed,
        },
        "totals": {"sessions": rows[-1].sessions_total if rows else 0, "served": player.served,
                   "failed": player.failed, "events": dict(player.events), "windows": len(rows)},
        "stopped": stopped.to_dict() if stopped else None,
        "half_open": player.ghosts.to_dict(),
        "soak_rss_mb": {"first": soak_rss[0], "last": soak_rss[-1], "max": max(soak_rss)} if soak_rss else None,
        "notes": list(player.notes),
        "overall": overall(judged),
        **judged.to_dict(),
        "windows": [r.to_dict() for r in rows],
    }
    return doc, judged


def overall(judged: Judged) -> str:
    """``FAIL``, ``PASS with findings`` or ``PASS`` (INCONCLUSIVE when nothing could be judged)."""
    verdicts = {v.verdict.value for v in judged.verdicts}
    if "FAIL" in verdicts:
        return "FAIL"
    if judged.findings:
        return "PASS with findings"
    if verdicts <= {"INCONCLUSIVE"}:
        return "INCONCLUSIVE"
    return "PASS"


__all__ = ["FORMAT", "build_document", "overall"]
