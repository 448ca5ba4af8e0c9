"""The judgments of ``certify-robot``: for each case of the catalogue (:mod:`conformance.observed.robot_catalogue`)
a function from a session's :class:`~.session.SessionView` to
:class:`~conformance.model.verdicts.CaseResult` objects, with the evidence (the
offending bytes, the session's wire log, the interval histogram, the pcap).

With ``--sessions N`` above 1 every ID gets the session as a parameter (``RB-S1-01[s2]``).
A case whose judgement itself raises becomes ERROR (the suite's fault), never a traceback.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable
from pathlib import Path

from ..harness.starvation import is_loopback
from ..model.signature import Sig, Signature
from ..model.verdicts import CaseResult, Verdict, WireLine, broken_verdict
from ..observed.connections import BY_BOX, BY_ROBOT, BY_ROBOT_RESET, BY_SUITE, SessionRecord
from ..observed.robot_catalogue import (
    ANY_FRAME,
    APPLIES,
    AWAIT_SPEC,
    CLOSE_SPEC,
    E4_SPEC,
    ERROR_SPEC,
    FALLBACK,
    FRAME_SPECS,
    INJECT_SPECS,
    JITTER_SPEC,
    RATE_SPEC,
    S1_SPEC,
    catalogue,
)
from ..observed.robot_frames import FrameRecord, byte_order_evidence
from ..observed.session import (
    LEFT_OPEN,
    SessionView,
    awaited,
    build_view,
    judge_order,
    not_awaited,
    runs_extension,
)
from ..observed.stream_timing import (
    jitter_excess_ms,
    jitter_starved,
    judge_jitter,
    judge_rate,
    rate_excess_ms,
    rate_starved,
    stream_stats,
)
from ..protocol import HEADER_LEN, Action, action_name, codec_for
from ..protocol.constants import POSE_BLOCK_LEN
from ..suite.record import CaseRecord
from .records import RunRecord
from .robot_starvation import robot_starved_note
from .wire_log import frame_wire, not_awaited_wire, session_wire

SHOWN = 5  # violations quoted per case
HELD_SHOWN = 40  # held answers listed by RB-A1-01
HISTOGRAM_BINS = 40

class Ctx:
    """What every check of one session needs."""

    def __init__(self, run: RunRecord, session: SessionRecord, view: SessionView, suffix: str) -> None:
        self.run, self.session, self.view, self.suffix = run, session, view, suffix
        self.config = run.config
        self.profile = run.config.profile
        #: E4 or S1: as forced by --extension on/off, else (auto) the session the robot ran
        self.extension = session_extension(run, session)
        self.records = sorted((r for rs in view.frames.values() for r in rs), key=lambda r: (r.t, r.conn, r.offset))
        self._wire: list[WireLine] | None = None

    @property
    def wire(self) -> list[WireLine]:
        if self._wire is None:
            self._wire = session_wire(self.session.conns, self.profile, self.view.t0)
        return self._wire

    def pcap(self, conn: int | None = None) -> str | None:
        for c in self.session.conns:
            if c.number == conn and c.pcap is not None:
                return str(c.pcap)
        return str(self.session.pcap) if self.session.pcap else None

    def answers(self) -> dict[tuple[int, int], str]:
        return {k: ex.answer_text or "nothing" for k, ex in self.view.exchanges.items()}

    def result(self, spec: CaseRecord, verdict: Verdict, message: str, observed: str = "", **kw: object) -> CaseResult:
        case = CaseResult(id=spec.id + self.suffix, title=spec.title, clauses=spec.clauses, level=spec.level,
                          verdict=verdict, message=message, requirement=spec.requirement, expected=spec.expect,
                          observed=observed or message, pcap=self.pcap())
        for key, value in kw.items():
            setattr(case, key, value)
        case.details.setdefault("session", self.session.number)
        return case


def session_extension(run: RunRecord, session: SessionRecord) -> bool:
    """Judge this session as E4? ``--extension on``/``off`` decide; ``auto`` (None) judges the session the robot
    runs: one that sends ProgIdx or the result request runs the revision's session."""
    forced = run.config.extension
    return runs_extension(session.conns) if forced is None else forced


# -- frame cases -----------------------------------------------------------------------------------
def frame_cases(ctx: Ctx) -> list[CaseResult]:
    records = ctx.records
    by_clause: dict[str, list[FrameRecord]] = {}
    for rec in records:
        if rec.error is not None:
            clause = rec.error.clause if rec.error.clause in FRAME_SPECS else FALLBACK.clauses[0]
            by_clause.setdefault(clause, []).append(rec)
    out = []
    for clause, spec in FRAME_SPECS.items():
        if clause == "F4":
            out.append(byte_order_case(ctx))
            continue
        applies, what = APPLIES.get(clause, ANY_FRAME)
        n = sum(1 for r in records if applies(r))
        bad = by_clause.get(clause, [])
        if not bad:
            if not n:
                out.append(ctx.result(spec, Verdict.SKIP, f"the robot sent no {what} ({len(records)} frame(s) in all)"))
            else:
                out.append(ctx.result(spec, Verdict.PASS, f"{n} {what}(s) checked, none breaks {clause}"))
            continue
        first = bad[0]
        verdict = broken_verdict(spec.level)  # B4 (a SHOULD): NON-STRICT; lenient profiles accept NaN
        lines = [f"+{(r.t - ctx.view.t0) * 1000:.1f} ms conn {r.conn} offset {r.offset}: {r.describe()}" for r in bad[:SHOWN]]
        if len(bad) > SHOWN:
            lines.append(f"… and {len(bad) - SHOWN} more")
        consequence = _consequence(first, records)
        ex = ctx.view.answer(first)
        out.append(ctx.result(
            spec, verdict,
            f"{len(bad)} of {max(n, len(bad))} frame(s) break {clause}; first on connection {first.conn}: "
            f"{first.error}{consequence}",
            "\n".join(lines), received_hex=first.raw[:1024].hex(" "),
            sent_hex=(ex.answer or b"").hex(" ") if ex else "", pcap=ctx.pcap(first.conn),
            wire=frame_wire(bad[:20], ctx.view.t0, ctx.answers()),
        ))
    return out


def _consequence(rec: FrameRecord, records: list[FrameRecord]) -> str:
    """F1 garbage right after a malformed frame on the same connection is usually its consequence."""
    if rec.error is None or rec.error.clause != "F1":
        return ""
    before = [r for r in records if r.conn == rec.conn and r.offset < rec.offset]
    if before and before[-1].error is not None and before[-1].offset + len(before[-1].raw) == rec.offset:
        return (f" (right after a malformed frame at offset {before[-1].offset} [{before[-1].error.clause}]: "
                "its header announced a length its bytes do not have)")
    return ""


def byte_order_case(ctx: Ctx) -> CaseResult:
    spec = FRAME_SPECS["F4"]
    evidence = [(r, byte_order_evidence(r, ctx.profile)) for r in ctx.records]
    swapped = [r for r, e in evidence if e == "swapped"]
    judged = [r for r, e in evidence if e is not None]
    order = f"{ctx.profile.byte_order}-endian header fields and {ctx.profile.float_byte_order}-endian values"
    if not judged:
        return ctx.result(spec, Verdict.SKIP, "no frame carried values that tell the byte order (all zero or none)")
    if not swapped:
        return ctx.result(spec, Verdict.PASS, f"{len(judged)} frame(s) with values read plausibly as {order}")
    first = swapped[0]
    return ctx.result(
        spec, Verdict.FAIL,
        f"{len(swapped)} of {len(judged)} frame(s) read as absurd values under {order} but plausibly byte-swapped: "
        f"the robot sends the other byte order; first on connection {first.conn}: {_swapped_example(first, ctx)}",
        received_hex=first.raw[:1024].hex(" "), pcap=ctx.pcap(first.conn),
        wire=frame_wire(swapped[:10], ctx.view.t0, ctx.answers()),
    )


def _swapped_example(rec: FrameRecord, ctx: Ctx) -> str:
    if rec.error is not None and rec.error.clause == "F2" and rec.raw[:4] == codec_for(ctx.profile.swapped(header=True)).start:
        return "the version field reads 01 00 in the profile's byte order: the header is the other way round"
    if rec.action in (Action.POSE, Action.REGISTER_POSE) and len(rec.raw) >= HEADER_LEN + POSE_BLOCK_LEN:
        straight = codec_for(ctx.profile).pose.unpack_from(rec.raw, HEADER_LEN)[1:]
        swapped = codec_for(ctx.profile.swapped(floats=True)).pose.unpack_from(rec.raw, HEADER_LEN)[1:]
        return (f"pose read as ({', '.join(f'{v:.3g}' for v in straight)}), byte-swapped "
                f"({', '.join(f'{v:.1f}' for v in swapped)})")
    return rec.describe()


# -- session cases -----------------------------------------------------------------------------------
def order_case(ctx: Ctx) -> CaseResult:
    spec = E4_SPEC if ctx.extension else S1_SPEC
    view = ctx.view
    order = judge_order(view, ctx.extension)
    steps = "\n".join(f"{name:<22} {view.ms(t)}" for name, t in order.steps.items())
    lines = [*order.violations, *order.missing]
    if order.not_judged:
        lines.append(f"not judged after {view.ms(view.cut.t) if view.cut else '?'} ({view.cut.why if view.cut else ''}): "
                     + ", ".join(order.not_judged))
    observed = "\n".join([*lines, *order.notes, "", "steps:", steps]).strip()
    common = {"wire": ctx.wire, "details": {"steps": {k: view.ms(v) for k, v in order.steps.items()},
                                            "session_end": ctx.session.end_reason}}
    if order.failed:
        # a close missing only because the robot left the connection open is the S5 defect seen from S1
        left_open = not order.violations and all(LEFT_OPEN in line for line in order.missing)
        return ctx.result(spec, Verdict.FAIL, "; ".join(lines), observed, **common,
                          signature=left_open_signature(ctx) if left_open else None)
    if order.not_judged:
        cut = view.cut
        return ctx.result(spec, Verdict.INCONCLUSIVE,
                          f"at {view.ms(cut.t if cut else None)} {cut.why if cut else 'the box refused a request'}; "
                          f"the robot may stop there (S2), so these steps are not judged: {', '.join(order.not_judged)}",
                          observed, **common)
    return ctx.result(spec, Verdict.PASS, f"all {len(order.steps)} steps in the canonical order"
                      + (f" ({'; '.join(order.notes)})" if order.notes else ""), observed, **common)


def awaited_case(ctx: Ctx) -> CaseResult:
    checked, bad = not_awaited(ctx.view, ctx.profile)
    if not ctx.view.commands:
        return ctx.result(AWAIT_SPEC, Verdict.SKIP, "no command connection")
    held, latencies = held_answers(ctx)
    how = ctx.config.latency_text()
    evidence = {"details": {"answer_latency": how, "answer_latencies": held}, "latencies_ms": latencies}
    if bad:
        first = bad[0]
        ex = ctx.view.answer(first.prev)
        frames = [first.prev, *([first.cur] if first.cur is not None else [])]
        return ctx.result(AWAIT_SPEC, Verdict.FAIL, f"{len(bad)} request(s) sent without awaiting the previous answer: "
                          + first.text, "\n".join([*(b.text for b in bad[:SHOWN]), "", how, *held]),
                          received_hex=b"".join(f.raw for f in frames).hex(" "),
                          sent_hex=(ex.answer or b"").hex(" ") if ex else "",
                          wire=not_awaited_wire(ctx.view, bad[:SHOWN]) + ctx.wire, **evidence)
    return ctx.result(AWAIT_SPEC, Verdict.PASS, f"{checked} follow-up request(s) on the command connection, each after "
                      f"the previous answer; {how}", "\n".join([f"{checked} follow-up request(s), each after the "
                                                                  "previous answer", how, *held]),
                      wire=ctx.wire, **evidence)


def held_answers(ctx: Ctx) -> tuple[list[str], list[float]]:
    """(lines, latencies in ms) of the answers the box held back on purpose on the command connections, in
    request order (at most HELD_SHOWN lines; the wire log has every answer)."""
    lines, latencies = [], []
    for conn in ctx.view.commands:
        for ex in conn.exchanges:
            if not ex.delay_s:
                continue
            sent = ctx.view.ms(ex.t_answer) if ex.t_answer is not None else "never (the robot closed first)"
            lines.append(f"conn {conn.number}: {action_name(ex.action) if ex.action is not None else '?'} at "
                         f"{ctx.view.ms(ex.t_request)}: answer held {ex.delay_s * 1000:.0f} ms, sent {sent}")
            if ex.t_answer is not None:
                latencies.append(round((ex.t_answer - ex.t_request) * 1000, 3))
    if len(lines) > HELD_SHOWN:
        lines[HELD_SHOWN:] = [f"… and {len(lines) - HELD_SHOWN} more held answers (the wire log has them)"]
    return lines, latencies


def rate_cases(ctx: Ctx) -> list[CaseResult]:
    view, cfg = ctx.view, ctx.config
    if not view.streams:
        return [ctx.result(s, Verdict.INCONCLUSIVE, "no stream connection") for s in (RATE_SPEC, JITTER_SPEC)]
    stream = view.streams[0]
    times = view.pose_times(stream)
    stats = stream_stats(times, ctx.profile.pose_rate_hz)
    if stats is None:
        return [ctx.result(s, Verdict.INCONCLUSIVE, f"{len(times)} pose(s): too few to measure a rate")
                for s in (RATE_SPEC, JITTER_SPEC)]
    histogram = {"values_ms": [round(v, 3) for v in stats.intervals_ms], "bins": HISTOGRAM_BINS,
                 "expected_ms": round(stats.period_ms, 3),
                 "title": f"pose send intervals on connection {stream.number}, at the box"}
    unreadable = sum(1 for r in view.frames.get(stream.number, []) if r.action is None)
    note = (f"\n{unreadable} chunk(s) of the stream had no readable header and are not counted as poses"
            if unreadable else "")
    out = []
    for spec, (ok, text), tolerance, starving, excess in (
        (RATE_SPEC, judge_rate(stats, cfg.rate_tolerance), f"±{cfg.rate_tolerance * 100:g} % of the declared rate",
         lambda: rate_starved(stats, times, cfg.rate_tolerance), lambda: rate_excess_ms(stats, cfg.rate_tolerance)),
        (JITTER_SPEC, judge_jitter(stats, cfg.jitter_tolerance), f"{cfg.jitter_tolerance * 100:g} % of the period",
         lambda: jitter_starved(stats, times, cfg.jitter_tolerance, is_loopback(stream.peer.host)),
         lambda: jitter_excess_ms(stats, cfg.jitter_tolerance)),
    ):
        details = {"interval_histogram": histogram, "stream": stats.describe(), "tolerance": tolerance,
                   "windows_hz": [round(w.rate_hz, 2) for w in stats.windows]}
        verdict = Verdict.PASS if ok else Verdict.FAIL
        # the frames' times are when the suite's event loop saw them: a stall of the suite's own can explain a breach
        starved = None if ok else starving()
        if starved is not None:
            verdict, text = Verdict.INCONCLUSIVE, f"{starved}. {text}"
        elif not ok:  # the verdict stands; a robot starved on this host is said to be
            text += robot_starved_note(excess(), times, stream.peer.host)
        out.append(ctx.result(spec, verdict, text, f"{text}\n{stats.describe()}{note}",
                              pcap=ctx.pcap(stream.number), details=details))
    return out


def left_open_signature(ctx: Ctx) -> Signature | None:
    """Left open ``stream`` (or ``command``, ``command+stream``): the robot's connections the suite had to close."""
    kinds = sorted({c.role for c in ctx.session.tcp if c.closed_by == BY_SUITE})
    return Signature(Sig.LEFT_OPEN, "+".join(kinds)) if kinds else None


def close_case(ctx: Ctx) -> CaseResult:
    lines, bad = [], []
    view = ctx.view
    for conn in ctx.session.tcp:
        how = {BY_ROBOT: "closed by the robot (FIN)", BY_ROBOT_RESET: "reset by the robot (RST)",
               BY_BOX: "closed by the box", BY_SUITE: "LEFT OPEN: closed by the suite"}.get(conn.closed_by or "", "open")
        line = f"{conn.label}: opened {view.ms(conn.t_open)}, {how} at {view.ms(conn.t_close)}"
        if conn.closed_by == BY_SUITE:
            line += f" ({conn.close_note.removeprefix('closed by the suite: ')})"
            bad.append(line)
        lines.append(line)
    if not lines:
        return ctx.result(CLOSE_SPEC, Verdict.SKIP, "no TCP connection")
    cut = view.cut
    if bad and cut is not None and cut.why.startswith("the run was interrupted"):
        return ctx.result(CLOSE_SPEC, Verdict.INCONCLUSIVE, f"{cut.why} with {len(bad)} connection(s) open",
                          "\n".join(lines), wire=ctx.wire)
    if bad:
        return ctx.result(CLOSE_SPEC, Verdict.FAIL, f"{len(bad)} connection(s) left open: {bad[0]}", "\n".join(lines),
                          wire=ctx.wire, signature=left_open_signature(ctx))
    return ctx.result(CLOSE_SPEC, Verdict.PASS, f"all {len(lines)} connection(s) closed", "\n".join(lines))


def inject_case(ctx: Ctx, name: str) -> CaseResult:
    spec, view = INJECT_SPECS[name], ctx.view
    delay = ctx.config.slow_delay_s
    trigger: tuple[float, str] | None = None
    for conn in ctx.session.conns:
        for ex in conn.exchanges:
            if name == "not-ready" and ex.action == Action.CYCLE_ON and ex.error_code == 1:
                trigger = trigger or (ex.t_answer or ex.t_request, "CycleOn answered 0001")
            elif name == "busy" and ex.action == Action.VISION_RESULT and ex.value == 202:
                trigger = trigger or (ex.t_answer or ex.t_request, "result request answered 202")
            elif name == "slow" and ex.answer is not None:
                trigger = min(trigger or (ex.t_request, ""), (ex.t_request, ""))
    if name == "slow" and trigger is not None:
        trigger = (trigger[0], f"every answer held back by {delay * 1000:.0f} ms, from the first request")
    for event in ctx.session.injected:
        if event.name == name:
            trigger = trigger or (event.t, event.note)
    if trigger is None:
        return ctx.result(spec, Verdict.INCONCLUSIVE, "nothing was injected: the robot never sent the request it applies to")
    t, what = trigger
    after = [r for r in ctx.records if r.t >= t and r.action is not None]
    cmds = [f"{action_name(r.action)} at {view.ms(r.t)}" for r in after if r.action != Action.POSE]
    poses = [r for r in after if r.action == Action.POSE]
    closes = [f"conn {c.number} ({c.role}) {c.closed_by} at {view.ms(c.t_close)}" for c in ctx.session.tcp
              if c.t_close is not None and c.t_close >= t]
    reaction = [f"requests after it: {', '.join(cmds[:8]) or 'none'}",
                f"poses after it: {len(poses)}" + (f" (last at {view.ms(poses[-1].t)})" if poses else ""),
                f"closes after it: {', '.join(closes) or 'none'}"]
    if name == "slow":
        checked, bad = awaited(view, ctx.profile)
        reaction.append(f"waited for every answer: {'no, see RB-A1-01' if bad else 'yes'} ({checked} follow-up requests)")
    return ctx.result(spec, Verdict.INFORMATIONAL, f"{what} at {view.ms(t)}; the robot then: " + "; ".join(reaction),
                      "\n".join([f"{what} at {view.ms(t)}", *reaction]), wire=ctx.wire)


# -- the run ------------------------------------------------------------------------------------------
def judge(run: RunRecord) -> list[CaseResult]:
    """Every case of every session, then missing sessions and the suite's own errors."""
    cases: list[CaseResult] = []
    many = run.config.sessions > 1
    for session in run.sessions:
        suffix = f"[s{session.number}]" if many else ""
        cases += judge_session(run, session, suffix)
    ran_e4 = any(session_extension(run, s) for s in run.sessions)
    for n in range(len(run.sessions) + 1, run.config.sessions + 1):
        spec = E4_SPEC if ran_e4 or run.config.extension else S1_SPEC
        cases.append(CaseResult(spec.id + f"[s{n}]", spec.title, spec.clauses, spec.level, Verdict.INCONCLUSIVE,
                                message=f"session {n} did not take place ({run.end_note})", requirement=spec.requirement,
                                expected=spec.expect))
    for n, error in enumerate(run.errors, 1):
        cases.append(_error_case(f"{ERROR_SPEC.id}[{n}]" if len(run.errors) > 1 else ERROR_SPEC.id, error))
    return cases


def judge_session(run: RunRecord, session: SessionRecord, suffix: str) -> list[CaseResult]:
    interrupted = run.end_note if run.end_reason == "interrupted" and session is run.sessions[-1] else ""
    try:
        view = build_view(session, run.config.profile, interrupted)
    except Exception as exc:  # noqa: BLE001 - the suite's fault, reported as ERROR
        return [_error_case(ERROR_SPEC.id + suffix, f"decoding session {session.number}: {_exc_line(exc)}")]
    ctx = Ctx(run, session, view, suffix)
    cases: list[CaseResult] = []
    checks: list[tuple[CaseRecord, Callable[[], list[CaseResult]]]] = [
        (FRAME_SPECS["F1"], lambda: frame_cases(ctx)),
        (E4_SPEC if ctx.extension else S1_SPEC, lambda: [order_case(ctx)]),
        (AWAIT_SPEC, lambda: [awaited_case(ctx)]),
        (RATE_SPEC, lambda: rate_cases(ctx)),
        (CLOSE_SPEC, lambda: [close_case(ctx)]),
        *((INJECT_SPECS[n], (lambda n=n: [inject_case(ctx, n)])) for n in run.config.inject),
    ]
    for spec, check in checks:
        t = time.perf_counter()
        try:
            found = check()
        except Exception as exc:  # noqa: BLE001
            found = [_error_case(spec.id + suffix, f"judging {spec.id}: {_exc_line(exc)}", spec)]
        for case in found:
            case.duration_s = time.perf_counter() - t
        cases += found
    return cases


def _exc_line(exc: BaseException) -> str:
    return traceback.format_exception_only(type(exc), exc)[-1].strip()


def _error_case(case_id: str, message: str, spec: CaseRecord = ERROR_SPEC) -> CaseResult:
    return CaseResult(case_id, spec.title, spec.clauses, spec.level, Verdict.ERROR, message=message,
                      requirement=spec.requirement, expected=spec.expect,
                      observed="the suite failed; this says nothing about the robot: rerun")


def pcap_paths(run: RunRecord) -> list[Path]:
    return [p for s in run.sessions for p in [s.pcap, *(c.pcap for c in s.conns)] if p is not None]


def extension_label(run: RunRecord) -> str:
    """The report's extension line: forced on or off, or (auto) which session each robot session ran."""
    forced = run.config.extension
    if forced is not None:
        return "forced on" if forced else "off"
    e4 = [s.number for s in run.sessions if session_extension(run, s)]
    if not e4:
        return "auto: S1 judged (the robot sent no ProgIdx or result request)"
    which = "" if len(run.sessions) == 1 else f" in session(s) {', '.join(map(str, e4))}"
    return f"auto: E4 judged{which} (the robot sent ProgIdx or the result request: the revision's session)"


__all__ = ["FRAME_SPECS", "INJECT_SPECS", "catalogue", "extension_label", "judge", "judge_session", "pcap_paths"]
