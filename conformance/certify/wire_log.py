"""The session's wire log for the report, seen from the box (``←`` from the robot, ``→`` the
answers), and the few frames a case quotes."""

from __future__ import annotations

from ..harness.transcript import Kind
from ..model.verdicts import WireLine
from ..observed.connections import ConnRecord
from ..observed.robot_frames import FrameRecord, judge_profile
from ..observed.session import NotAwaited, SessionView
from ..protocol import Frame, Profile, ProtocolError, StreamDecoder, TransferType, decode_datagram
from ..protocol.constants import Action


def _chunk_summary(decoder: StreamDecoder, data: bytes) -> tuple[str, bool]:
    """(summary, only whole pose requests/answers without errors)."""
    parts, poses_only = [], True
    for event in decoder.feed(data):
        if isinstance(event, Frame):
            parts.append(event.describe())
            poses_only = poses_only and event.action is Action.POSE and not event.error_code
        else:
            parts.append(f"[{event.clause}] {event.message}")
            poses_only = False
    if decoder.buffered:
        parts.append(f"({decoder.buffered} bytes of an incomplete frame)")
        poses_only = False
    return "; ".join(parts), poses_only and bool(parts)


def session_wire(conns: list[ConnRecord], profile: Profile, t0: float, keep_poses: int = 3,
                 limit: int = 1500) -> list[WireLine]:
    """The session's connections merged in time. Pose traffic on stream connections keeps
    its first and last ``keep_poses`` chunks each way; the rest is one line (the pcap has it)."""
    judged = judge_profile(profile)
    rows: list[tuple[float, int, WireLine, bool]] = []
    for conn in conns:
        decoders = {Kind.RECV: StreamDecoder(judged, TransferType.ROBOT_TO_BOX),
                    Kind.SEND: StreamDecoder(judged, TransferType.BOX_TO_ROBOT)}
        for ev in conn.transcript.events:
            t_ms = round((ev.t - t0) * 1000, 3)
            if ev.kind in decoders:
                if conn.transport == "udp":
                    expect = TransferType.ROBOT_TO_BOX if ev.kind == Kind.RECV else TransferType.BOX_TO_ROBOT
                    try:
                        summary, pose = decode_datagram(ev.data, judged, expect).describe(), False
                    except ProtocolError as exc:
                        summary, pose = f"[{exc.clause}] {exc.message}", False
                else:
                    summary, pose = _chunk_summary(decoders[ev.kind], ev.data)
                if ev.note:
                    summary = f"{ev.note}: {summary}"
                arrow = "←" if ev.kind == Kind.RECV else "→"
                line = WireLine(t_ms, conn.number, arrow, ev.kind, ev.data.hex(" "), summary)
                rows.append((ev.t, conn.number, line, pose and conn.role == "stream"))
            else:
                note = ev.note or ""
                if ev.kind == Kind.CONNECT:
                    note += f" ({conn.role}, {conn.transport} {conn.peer} → {conn.local})"
                rows.append((ev.t, conn.number, WireLine(t_ms, conn.number, "·", ev.kind, "", note.strip()), False))
    rows.sort(key=lambda r: r[0])
    keep = set()
    for conn in conns:
        pose_rows = [i for i, r in enumerate(rows) if r[1] == conn.number and r[3]]
        keep.update(pose_rows[: 2 * keep_poses] + pose_rows[-2 * keep_poses :])
    out: list[WireLine] = []
    omitted: dict[int, int] = {}
    for i, (_t, conn_no, line, pose) in enumerate(rows):
        if pose and i not in keep:
            if conn_no not in omitted:
                out.append(WireLine(line.t_ms, conn_no, "·", "note", "", "__omitted__"))
            omitted[conn_no] = omitted.get(conn_no, 0) + 1
            continue
        out.append(line)
    out = [WireLine(w.t_ms, w.conn, w.direction, w.kind, w.hex,
                    f"… {omitted[w.conn]} chunks of pose traffic omitted here (all of them are in the pcap)")
           if w.summary == "__omitted__" else w for w in out]
    if len(out) > limit:
        out = out[: limit - 1] + [WireLine(out[limit - 1].t_ms, 0, "·", "note", "",
                                           f"… {len(out) - limit + 1} more lines in the pcap")]
    return out


def frame_wire(records: list[FrameRecord], t0: float, answers: dict[tuple[int, int], str] | None = None) -> list[WireLine]:
    """Wire lines for a few frames (a case's offending frames), with the box's answer if any."""
    lines = []
    for rec in records:
        lines.append(WireLine(round((rec.t - t0) * 1000, 3), rec.conn, "←", "recv", rec.raw[:512].hex(" "),
                              f"offset {rec.offset}: {rec.describe()}"))
        answer = (answers or {}).get((rec.conn, rec.offset))
        if answer:
            lines.append(WireLine(round((rec.t - t0) * 1000, 3), rec.conn, "→", "send", "", f"box answered {answer}"))
    return lines


def not_awaited_wire(view: SessionView, bad: list[NotAwaited]) -> list[WireLine]:
    """The frames that show each violation: the request, the one sent too early, and the answer it did not await."""
    t0, out = view.t0, []
    for b in bad:
        ex = view.answer(b.prev)
        out.append(WireLine(round((b.prev.t - t0) * 1000, 3), b.conn, "←", "recv", b.prev.raw.hex(" "),
                            f"{b.prev.describe()} (its answer is not awaited)"))
        if b.cur is not None:
            out.append(WireLine(round((b.cur.t - t0) * 1000, 3), b.conn, "←", "recv", b.cur.raw.hex(" "),
                                f"{b.cur.describe()}: sent {(b.cur.t - b.prev.t) * 1000:.1f} ms after it, "
                                "before its answer"))
        if ex is not None and ex.answer is not None and b.answered is not None:
            out.append(WireLine(round((b.answered - t0) * 1000, 3), b.conn, "→", "send", ex.answer.hex(" "),
                                f"the answer to {b.prev.describe()}: {ex.answer_text}"
                                + (f" (held {ex.delay_s * 1000:.0f} ms, as a box takes time)" if ex.delay_s else "")))
    out.append(WireLine(0.0, 0, "·", "note", "", "the session's whole wire log follows"))
    return out
