"""What report.html shows of a root cause's diagnosis: the hypotheses, the experiments with their bytes, the repro."""

from __future__ import annotations

from typing import Any

from ..model.verdicts import RootCause

#: at most this many exchanges per experiment, and bytes per frame, are shown (summary.json keeps 12 exchanges)
SHOWN_EXCHANGES = 6
SHOWN_BYTES = 48


def _hex(text: str) -> str:
    data = bytes.fromhex(text)
    shown = data[:SHOWN_BYTES].hex(" ")
    return shown + (f" … ({len(data)} bytes)" if len(data) > SHOWN_BYTES else "")


def _lines(exchange: dict[str, Any]) -> list[str]:
    out = []
    readings = exchange.get("readings", [])
    for i, sent in enumerate(exchange.get("sent", [])):
        out.append(f"→ {_hex(sent)}")
        reading = readings[i] if i < len(readings) else None
        if reading is None:
            continue
        answers = reading.get("answers", [])
        out += [f"← {_hex(a['hex'])}" for a in answers]
        if reading.get("closed"):
            out.append("← (closed)")
        elif not answers:
            out.append("← (no answer)")
    return out


def diagnosis_view(rc: RootCause) -> dict[str, Any] | None:
    """The diagnosis of one root cause for the template (None when no diagnosis ran)."""
    d = rc.diagnosis
    if not d:
        return None
    experiments = [{"name": e.get("name", ""), "question": e.get("question", ""), "finding": e.get("finding", ""),
                    "lines": [line for x in e.get("exchanges", [])[:SHOWN_EXCHANGES] for line in (*_lines(x), "")],
                    "count": e.get("exchange_count", 0)} for e in d.get("experiments", [])]
    repro = d.get("repro") or {}
    return {"confirmed": bool(d.get("confirmed")), "catalogue_title": d.get("catalogue_title", ""),
            "hypotheses": d.get("hypotheses", []), "experiments": experiments, "repro": repro.get("file", ""),
            "phase_s": d.get("phase_s")}
