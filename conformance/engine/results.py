"""What a finished case becomes: its verdict, its evidence, its :class:`CaseResult`.

The pytest plugin forwards here: :func:`attach_evidence` before the case (a pcap
written as the case runs), :func:`result_of` after it (the verdict from what the case
raised, the requirement and bytes, the clause it judged and the defect's signature).
"""

from __future__ import annotations

import traceback
from pathlib import Path
from typing import Any

from ..harness.target import Unreachable
from ..harness.transcript import Kind, Transcript
from ..model.signature import Signature
from ..model.verdicts import CaseResult, Verdict, broken_verdict
from ..runtime.settings import SuiteSettings
from ..suite.case_context import CaseContext
from ..suite.case_judge import CaseVerdict
from ..suite.record import CaseRecord
from .wirelog import wire_lines


def attach_evidence(transcript: Transcript, settings: SuiteSettings, case_id: str) -> Path | None:
    """Subscribe a pcap writer to the case's transcript (synthesised or live); its path."""
    if settings.pcap_dir is None or settings.capture == "off":
        return None
    settings.pcap_dir.mkdir(parents=True, exist_ok=True)
    path = settings.pcap_dir / f"{safe_name(case_id)}.pcapng"
    if settings.capture == "live":
        from ..evidence.live import LiveCapture  # needs privileges; says so clearly

        capture = LiveCapture(path=path, case_id=case_id)
        transcript.listeners.append(capture)  # type: ignore[arg-type]
        capture.start()
    else:
        from ..evidence.pcap import PcapRecorder

        transcript.listeners.append(PcapRecorder(path, case_id=case_id))
    return path


#: A verdict quotes at most this many bytes (the pcap, when one is written, has up to the receive budget).
QUOTED_BYTES = 4096


def bounded_hex(data: bytes) -> str:
    """The hex a report quotes: all of ``data`` up to :data:`QUOTED_BYTES`, then how many there were."""
    if len(data) <= QUOTED_BYTES:
        return data.hex(" ")
    return data[:QUOTED_BYTES].hex(" ") + f" … ({len(data)} bytes in all)"


def safe_name(case_id: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in case_id)


def classify(exc: BaseException | None, info: CaseRecord, ctx: CaseContext | None,
             skipped: bool = False) -> tuple[Verdict, dict[str, Any]]:
    """The verdict and the report fields for what the case raised (None: it returned)."""
    if exc is None:
        if ctx is not None and ctx.informational is not None:
            return Verdict.INFORMATIONAL, {"message": ctx.informational, "observed": ctx.informational}
        return Verdict.PASS, {"message": ""}
    if isinstance(exc, CaseVerdict):
        return exc.verdict, {
            "message": exc.message, "requirement": exc.requirement, "expected": exc.expected,
            "observed": exc.observed, "sent_hex": bounded_hex(exc.sent), "received_hex": bounded_hex(exc.received),
            "judged": exc.judged, "signature": exc.signature,
        }
    if isinstance(exc, Unreachable):
        return Verdict.INCONCLUSIVE, {"message": f"box unreachable: {exc}"}
    if skipped:
        return Verdict.SKIP, {"message": str(getattr(exc, "msg", exc))}
    if isinstance(exc, AssertionError):
        message = str(exc).splitlines()[0] if str(exc) else "assertion failed"
        return broken_verdict(info.level), {"message": message}  # judged: the case's clauses
    tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)[-3:])
    return Verdict.ERROR, {"message": f"suite error: {type(exc).__name__}: {exc}", "observed": tb}


def result_of(info: CaseRecord, ctx: CaseContext | None, exc: BaseException | None, duration_s: float,
              skipped: bool = False) -> CaseResult:
    """The case's result, with its evidence. A non-PASS verdict always carries a requirement
    (default: the case's clauses, level and title), the bytes, and the clause it judged,
    which ``clauses`` then also names (so the clause table marks what was judged)."""
    verdict, fields = classify(exc, info, ctx, skipped)
    judged = tuple(c for c in fields.pop("judged", ()) if c)
    signature: Signature | None = fields.pop("signature", None)
    if verdict is not Verdict.PASS:
        fields["requirement"] = fields.get("requirement") or info.words
        if ctx is not None and not fields.get("sent_hex") and ctx.last_sent:
            fields["sent_hex"] = bounded_hex(ctx.last_sent)
        if verdict in (Verdict.FAIL, Verdict.NON_STRICT) and not judged:
            judged = info.clauses
        if not signature and verdict in (Verdict.FAIL, Verdict.NON_STRICT):
            signature = Signature.own(info.id)
    result = CaseResult(
        id=info.id, title=info.title, clauses=tuple(dict.fromkeys((*info.clauses, *judged))), level=info.level,
        verdict=verdict, duration_s=duration_s, expected=fields.pop("expected", "") or info.expect,
        pcap=str(ctx.pcap) if ctx is not None and ctx.pcap is not None else None,
        judged=judged if verdict is not Verdict.PASS else (), signature=signature, **fields,
    )
    if ctx is not None:
        result.wire = wire_lines(ctx.transcript, ctx.profile)
        result.latencies_ms = list(ctx.latencies_ms)
        result.details = dict(ctx.details)
        result.details["max_open_connections"] = max_open(ctx.transcript)
    return result


def max_open(transcript: Transcript) -> int:
    """The most TCP connections the case held open at once."""
    open_now, most = set(), 0
    for event in transcript.events:
        info = transcript.connections.get(event.conn)
        if info is None or info.transport != "tcp":
            continue
        if event.kind == Kind.CONNECT:
            open_now.add(event.conn)
            most = max(most, len(open_now))
        elif event.kind in (Kind.CLOSE, Kind.ABORT, Kind.PEER_RESET, Kind.PEER_CLOSE):
            open_now.discard(event.conn)
    return most
