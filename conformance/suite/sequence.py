"""Scripted sequences (``isight-sequence-1`` JSON files): the runner.

The runner executes the steps of a loaded sequence on a case's recorded
connections, judges each expectation with :func:`~.judge.check` and is bounded by
an overall deadline. The format and its loader are in :mod:`.sequence_format`, the
background pose stream in :mod:`.pose_stream`; their public names are re-exported
here, so ``from conformance.suite.sequence import load, PoseStream`` keeps working.
"""

from __future__ import annotations

import random
import time
from collections.abc import Iterator
from typing import Any

from ..harness.client import Answer, Outcome, Silence, TcpConnection
from ..model.verdicts import Level
from ..protocol import Action, Codec, Frame, peek_action, request
from .case_judge import Expect, Inconclusive, answered, answered_error, check, fail
from .pose_stream import (
    DEFAULT_POSE,
    PoseStream,
    StreamResult,
    judge_stream,
    latency_figures,
    percentile,
    trajectory_poses,
)
from .sequence_format import (
    _SHORT,
    FORMAT,
    SHIPPED_DIR,
    STEP_SPEC,
    Sequence,
    SequenceError,
    action_of,
    hex_bytes,
    load,
    seconds,
    shipped,
    verb_of,
)

__all__ = [
    "DEFAULT_POSE", "FORMAT", "SHIPPED_DIR", "STEP_SPEC", "PoseStream", "Sequence", "SequenceError", "SequenceRunner",
    "StreamResult", "action_of", "expectation", "frame_of", "hex_bytes", "judge_stream", "latency_figures", "load",
    "percentile", "pieces_of", "run_sequence", "seconds", "shipped", "trajectory_poses", "verb_of",
]


# -- expectations and frames ---------------------------------------------------------------------


def expectation(spec: Any, action: Action | None) -> Expect:
    if spec is None or spec == "ok":
        return answered(action, [0])
    if spec == "answered":
        return answered(action)
    if spec == "error":
        return answered_error(action)
    if isinstance(spec, str):
        return _SHORT[spec]  # type: ignore[return-value]
    errors = [int(e, 16) for e in spec["errors"]] if "errors" in spec else None
    out = answered(action, errors, spec.get("values"))
    for alt in spec.get("or", ()):
        out = out | _SHORT[alt]  # type: ignore[operator]
    return out


def frame_of(step: dict[str, Any], codec: Codec) -> Frame:
    """The request a step names, its blocks by position (the codec applies the profile's first index)."""
    action = action_of(step["request"])
    if action in (Action.POSE, Action.REGISTER_POSE):
        return request(action, codec.pose_blocks(step.get("poses", [DEFAULT_POSE])))
    if action is Action.TOLERANCE:
        return request(action, codec.tolerance_blocks(step.get("tolerances", [0.5])))
    if action is Action.PROG_IDX:
        return request(action, codec.value_blocks(step.get("values", [1])))
    return request(action)


def pieces_of(data: bytes, split: dict[str, Any]) -> list[bytes]:
    """R3: ``data`` cut as the split spec says (every byte, random 1-8 byte pieces, or given sizes)."""
    how = split["pieces"]
    if how == "bytes":
        sizes: Iterator[int] = iter([1] * len(data))
    elif how == "random":
        rng = random.Random(split.get("seed", 1))
        sizes = iter(lambda: rng.randint(1, 8), None)
    else:
        sizes = iter(list(how) + [len(data)])
    out, pos = [], 0
    while pos < len(data):
        n = next(sizes)
        out.append(data[pos : pos + n])
        pos += n
    return out


# -- the runner ---------------------------------------------------------------------------------------


class SequenceRunner:
    """Runs one sequence on a case's context; every wait is bounded by the overall deadline."""

    def __init__(self, isight: Any, seq: Sequence) -> None:
        self.isight, self.seq = isight, seq
        self.conns: dict[str, list[TcpConnection]] = {}
        self.streams: dict[str, tuple[PoseStream, dict[str, Any], str]] = {}
        self.figures: dict[str, Any] = {"file": seq.path.name, "steps": 0, "requests": 0, "streams": []}
        self.deadline = 0.0
        self.connected_once = False

    def run(self) -> None:
        isight, seq = self.isight, self.seq
        if "extension" in seq.requires:
            isight.require_extension()
        budget = seq.budget_s(isight.settings)
        self.figures["deadline_s"] = round(budget, 3)
        self.deadline = time.monotonic() + budget
        try:
            self._steps(seq.steps, "steps")
            for name in list(self.streams):
                self._stop(name, "end of sequence")
        finally:
            for stream, _, _ in self.streams.values():
                stream.stop()
            for conns in self.conns.values():  # before the liveness check that may follow
                for conn in conns:
                    conn.close("end of sequence")
            isight.details["sequence"] = self.figures

    def _steps(self, steps: list[dict[str, Any]], where: str) -> None:
        for i, step in enumerate(steps):
            verb = verb_of(step)
            path = f"{where}[{i}] ({verb})"
            if time.monotonic() > self.deadline:
                raise Inconclusive(f"sequence {self.seq.id} passed its overall deadline "
                                   f"({self.figures['deadline_s']} s) before {path}")
            self.figures["steps"] += 1
            if verb != "repeat":
                self.isight.transcript.note(f"{path}: {step.get('note') or _summary(step, verb)}")
            getattr(self, "_" + verb)(step, path)

    # -- helpers --------------------------------------------------------------------------------
    def _level(self, step: dict[str, Any]) -> Level:
        return Level(step.get("level", self.seq.level))

    def _wait(self, timeout: Any, path: str) -> float:
        want = seconds(timeout or "time_out", self.isight.settings)
        left = self.deadline - time.monotonic()
        if left <= 0.001:
            raise Inconclusive(f"sequence {self.seq.id} passed its overall deadline at {path}")
        return min(want, left)

    def _one(self, name: str, path: str) -> TcpConnection:
        conns = self.conns.get(name)
        if not conns:
            raise Inconclusive(f"{path}: connection {name!r} is not open (closed earlier, or the box refused it)")
        return conns[0]

    def _judge(self, outcome: Outcome, step: dict[str, Any], action: Action | None, path: str, sent: bytes,
               default: Any = "ok", waited: float | None = None) -> None:
        if "inconclusive" in step and expectation(step["inconclusive"], action).matches(outcome):
            because = step["inconclusive"].get("because", "") if isinstance(step["inconclusive"], dict) else ""
            raise Inconclusive(f"{path}: {because or 'the rest cannot be judged'}: the box {outcome.describe()}")
        if isinstance(outcome, Silence) and waited is not None and waited < seconds(step.get("timeout") or "time_out", self.isight.settings):
            raise Inconclusive(f"sequence {self.seq.id} passed its overall deadline waiting at {path}")
        level = self._level(step)
        expect = expectation(step.get("expect", default), action)
        requirement = step.get("requirement") or f"{', '.join(self.seq.clauses)}: {self.seq.title}, {path}"
        if level is Level.MAY:
            if not expect.matches(outcome):
                self.isight.inform(f"{path}: the box {outcome.describe()} (expected {expect.text})")
            return
        check(outcome, expect, level, requirement, sent=sent, judged=tuple(self.seq.clauses),
              profile=self.isight.profile)

    def _record(self, outcome: Outcome) -> None:
        self.figures["requests"] += 1
        if isinstance(outcome, Answer):
            self.isight.latencies_ms.append(outcome.latency_s * 1000)

    # -- verbs ------------------------------------------------------------------------------------
    def _open(self, step: dict[str, Any], path: str) -> None:
        name, count = step["open"], step.get("count")
        kind = step.get("target", "stream" if name.startswith("stream") else "command")
        target = self.isight.session.stream_target() if kind == "stream" else self.isight.target
        for old in self.conns.pop(name, []):  # opening an open name replaces it
            old.close(f"{path}: reopened")
        conns = self.conns.setdefault(name, [])
        for i in range(count or 1):
            left = self.deadline - time.monotonic()
            try:
                conns.append(self.isight.connect(f"{name}#{i + 1}" if count else name, target,
                                                 time_out_s=min(self.isight.time_out_s, max(0.05, left))))
            except Inconclusive as exc:
                if count:  # a group: the box may bound its resources; record how many it took
                    self.figures.setdefault("refused", {})[name] = f"{len(conns)} of {count} connected; then {exc}"
                    return
                if not self.connected_once:
                    raise
                raise fail(self._level(step), f"{', '.join(self.seq.clauses)}: the box keeps accepting connections ({path})",
                           "the connection is accepted within time_out", str(exc), judged=tuple(self.seq.clauses)) from None
            self.connected_once = True

    def _close(self, step: dict[str, Any], path: str) -> None:
        for conn in self.conns.pop(step["close"], []):
            conn.close(path)

    def _abort(self, step: dict[str, Any], path: str) -> None:
        for conn in self.conns.pop(step["abort"], []):
            conn.abort(path)

    def _send_on(self, conn: TcpConnection, data: bytes, step: dict[str, Any], note: str) -> float:
        start = time.monotonic()
        if "split" in step:
            conn.send_pieces(pieces_of(data, step["split"]), step["split"].get("gap_ms", 0) / 1000, note)
        else:
            conn.send(data, note)
        return start

    def _request(self, step: dict[str, Any], path: str) -> None:
        conn = self._one(step.get("on", "command"), path)
        frame = frame_of(step, self.isight.codec)
        data = conn.codec.encode(frame)
        self._exchange(conn, data, step, frame.action, path, step.get("note") or f"{frame.action.name} request")

    def _exchange(self, conn: TcpConnection, data: bytes, step: dict[str, Any], action: Action | None, path: str,
                  note: str, default: Any = "ok") -> None:
        self.isight.last_sent = data
        wait = self._wait(step.get("timeout"), path)
        start = self._send_on(conn, data, step, note)
        outcome = conn.next_outcome(wait, since=start)
        self._record(outcome)
        self._judge(outcome, step, action, path, data, default, waited=wait)

    def _raw(self, step: dict[str, Any], path: str) -> None:
        conn = self._one(step.get("on", "command"), path)
        data = hex_bytes(step["raw"], step.get("times", 1))
        action = _action_byte(data)
        note = step.get("note") or "raw bytes"
        if step.get("probe"):
            outcome = self.isight.send_malformed(data, note, conn=conn)
            self._record(outcome)
            self._judge(outcome, step, action, path, data, "not-ok")
        else:
            self._exchange(conn, data, step, action, path, note, "not-ok")

    def _send(self, step: dict[str, Any], path: str) -> None:
        data = hex_bytes(step["send"], step.get("times", 1))
        for conn in self.conns.get(step.get("on", "command"), []):
            self._send_on(conn, data, step, step.get("note") or "bytes (no answer awaited)")

    def _burst(self, step: dict[str, Any], path: str) -> None:
        conn = self._one(step.get("on", "command"), path)
        items = step["burst"] * step.get("times", 1)
        frames = [frame_of(item, self.isight.codec) for item in items]
        data = b"".join(conn.codec.encode(f) for f in frames)
        self.isight.last_sent = data
        start = time.monotonic()
        conn.send(data, step.get("note") or f"{len(frames)} requests in one segment (R4)")
        for k, (item, frame) in enumerate(zip(items, frames)):
            wait = self._wait(None, path)
            # a full time_out wait is the connection's own (None): the bounded-time rules for a later frame of one
            # write apply (harness.waits.COALESCED)
            outcome = conn.next_outcome(None if wait >= conn.time_out_s else wait, since=start)
            self._record(outcome)
            self._judge(outcome, {**step, **item}, frame.action, f"{path} answer {k + 1}/{len(frames)}",
                        conn.codec.encode(frame), waited=wait)

    def _stream(self, step: dict[str, Any], path: str) -> None:
        name = step["stream"]
        conn = self._one(name, path)
        settings = self.isight.settings
        rate = self.isight.profile.pose_rate_hz if step.get("rate", "profile") == "profile" else float(step["rate"])
        duration = seconds(step["duration"], settings) if "duration" in step else None
        if duration is None and not step.get("background"):
            duration = settings.stream_seconds
        stream = PoseStream(conn, rate, duration, self.isight.time_out_s,
                            trajectory_poses(step.get("trajectory", "primer"), rate, duration),
                            expectation(step.get("expect"), Action.POSE))
        self.streams[name] = (stream.start(), step, path)
        if not step.get("background"):
            self._stop(name, path)

    def _stop(self, name: Any, path: str) -> None:
        if isinstance(name, dict):
            name = name["stop"]
        stream, step, where = self.streams.pop(name)
        result = stream.stop()
        self.isight.latencies_ms.extend(result.latencies_ms)
        self.figures["streams"].append({"step": where, **result.figures()})
        level = self._level(step)
        what = f"{self.seq.title}, pose stream of {where}"
        if level is Level.MAY:
            if result.failed or result.lost > step.get("max_lost", 0):
                self.isight.inform(f"{where}: {result.figures()}")
            return
        judge_stream(result, level, what, step.get("max_lost", 0), step.get("backlog", False), tuple(self.seq.clauses))

    def _sleep(self, step: dict[str, Any], path: str) -> None:
        end = time.monotonic() + seconds(step["sleep"], self.isight.settings)
        if end > self.deadline:
            raise Inconclusive(f"sequence {self.seq.id}: {path} would pass the overall deadline")
        while (left := end - time.monotonic()) > 0:
            for name, (stream, _, _) in list(self.streams.items()):
                if stream.result.failed:  # judge a failed background stream now, not after the sleep
                    self._stop(name, path)
            time.sleep(min(left, 0.05))

    def _repeat(self, step: dict[str, Any], path: str) -> None:
        for i in range(step["repeat"]):
            self._steps(step["steps"], f"{path}#{i + 1}.steps")


def _action_byte(data: bytes) -> Action | None:
    try:
        action = peek_action(data)
        return None if action is None else Action(action)
    except ValueError:
        return None


def _summary(step: dict[str, Any], verb: str) -> str:
    value = step[verb]
    on = f" on {step['on']}" if "on" in step else ""
    return f"{verb} {value if not isinstance(value, list) else f'{len(value)} items'}{on}"


def run_sequence(isight: Any, seq: Sequence) -> None:
    SequenceRunner(isight, seq).run()
