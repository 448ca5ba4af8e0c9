"""Scripted sequences (``isight-sequence-1`` JSON files): loader, runner, pose stream.

A sequence is data: a header (``id``, ``title``, ``clauses``, ``level``) and a list
of steps, each an object whose *verb* key says what it does (``open``, ``request``,
``stream``, ``repeat`` …; ``vectors/sequences/README.md`` documents them). The
loader validates a file itself, with messages naming the file and the step (no
jsonschema at run time); the runner executes the steps on a case's recorded
connections, judges each expectation with :func:`~.judge.check` and is bounded by
an overall deadline. :class:`PoseStream` sends poses on a fixed clock from a
background thread and matches the pipelined answers in order (S6, T2).
"""

from __future__ import annotations

import json
import math
import random
import re
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..endpoints.trajectory import PrimerTrajectory
from ..harness.client import Answer, Malformed, Outcome, Silence, TcpConnection
from ..protocol import Action, Frame, pose_blocks, request, tolerance_blocks, value_blocks
from ..vectors import REPO_VECTORS
from .catalogue import _CLAUSE
from .judge import CLOSED, NOT_OK, SILENCE, Expect, Inconclusive, answered, answered_error, check, fail
from .verdicts import Level

FORMAT = "isight-sequence-1"
SHIPPED_DIR = REPO_VECTORS / "sequences"
_ACTIONS = {"none": Action.NONE, "ping": Action.NONE, "cycleon": Action.CYCLE_ON, "cycleoff": Action.CYCLE_OFF,
            "pose": Action.POSE, "registerpose": Action.REGISTER_POSE, "tolerance": Action.TOLERANCE,
            "progidx": Action.PROG_IDX, "visionresult": Action.VISION_RESULT, "result": Action.VISION_RESULT}
_SHORT = {"ok": None, "answered": None, "error": None, "not-ok": NOT_OK, "silence": SILENCE, "closed": CLOSED,
          "silence-or-closed": SILENCE | CLOSED, "any": Expect("anything", lambda o: True)}
_SEQ_ID = re.compile(r"^SEQ-[A-Z0-9][A-Z0-9-]*$")
_CAMEL = "NONE, CycleOn, CycleOff, Pose, RegisterPose, Tolerance, ProgIdx, VisionResult"


class SequenceError(ValueError):
    """A sequence file that does not follow the format; str() names the file and the step."""


# -- loading and validation ----------------------------------------------------------------------


def action_of(name: str) -> Action:
    key = name.lower().replace("_", "").replace("-", "").replace(" ", "")
    if key not in _ACTIONS:
        raise ValueError(f"unknown action {name!r}; expected one of {_CAMEL}")
    return _ACTIONS[key]


def hex_bytes(text: str, times: int = 1) -> bytes:
    try:
        return bytes.fromhex(text.replace(":", " ")) * times
    except ValueError:
        raise ValueError(f"not hex bytes: {text[:40]!r}") from None


def _num(lo: float, hi: float, sym: tuple[str, ...] = (), integer: bool = False) -> Callable[[Any], None]:
    def v(x: Any) -> None:
        if isinstance(x, str) and x in sym:
            return
        ok = isinstance(x, int) if integer else isinstance(x, (int, float))
        if isinstance(x, bool) or not ok or not lo <= x <= hi:
            kind = "an integer" if integer else "a number"
            raise ValueError(f"expected {kind} in [{lo:g}, {hi:g}]" + (f" or one of {', '.join(sym)}" if sym else "")
                             + f", not {x!r}")
    return v


def _of(*choices: str) -> Callable[[Any], None]:
    def v(x: Any) -> None:
        if x not in choices:
            raise ValueError(f"expected one of {', '.join(choices)}, not {x!r}")
    return v


def _text(x: Any) -> None:
    if not isinstance(x, str) or not x:
        raise ValueError(f"expected a non-empty string, not {x!r}")


def _bool(x: Any) -> None:
    if not isinstance(x, bool):
        raise ValueError(f"expected true or false, not {x!r}")


def _list(item: Callable[[Any], None], lo: int = 1, hi: int = 255) -> Callable[[Any], None]:
    def v(x: Any) -> None:
        if not isinstance(x, list) or not lo <= len(x) <= hi:
            raise ValueError(f"expected a list of {lo} to {hi} items, not {x!r}"[:160])
        for i, e in enumerate(x):
            try:
                item(e)
            except ValueError as exc:
                raise ValueError(f"item {i}: {exc}") from None
    return v


def _action(x: Any) -> None:
    _text(x)
    action_of(x)


def _hex(x: Any) -> None:
    _text(x)
    hex_bytes(x)


def _expect(x: Any) -> None:
    if isinstance(x, str):
        _of(*_SHORT)(x)
        return
    if not isinstance(x, dict) or not x:
        raise ValueError(f"expected one of {', '.join(_SHORT)} or an object with errors/values/or, not {x!r}")
    _keys(x, {"errors": _list(_errcode, 1, 16), "values": _list(_num(-2**31, 2**31 - 1, integer=True), 1, 16),
              "or": _list(_of("silence", "closed", "silence-or-closed"), 1, 3), "because": _text})


def _errcode(x: Any) -> None:
    if not (isinstance(x, str) and len(x) == 4 and all(c in "0123456789abcdefABCDEF" for c in x)):
        raise ValueError(f"an error code is 4 hex digits in quotes, e.g. \"0000\" or \"1001\", not {x!r}")


def _keys(obj: dict[str, Any], spec: dict[str, Callable[[Any], None]], required: tuple[str, ...] = ()) -> None:
    for key in required:
        if key not in obj:
            raise ValueError(f"missing field {key!r}")
    for key, value in obj.items():
        if key not in spec:
            raise ValueError(f"unknown field {key!r}; allowed: {', '.join(spec)}")
        try:
            spec[key](value)
        except ValueError as exc:
            raise ValueError(f"field {key!r}: {exc}") from None


_ON = {"on": _text}
_TIMEOUT = _num(0.001, 3600, ("time_out", "vision_time_out"))
_SPLIT = {"pieces": lambda x: (_of("bytes", "random")(x) if isinstance(x, str) else _list(_num(1, 65535, integer=True), 1, 65535)(x)),
          "gap_ms": _num(0, 1000), "seed": _num(0, 2**31, integer=True)}
_REQ = {**_ON, "expect": _expect, "timeout": _TIMEOUT, "split": lambda x: _keys(x, _SPLIT, ("pieces",)),
        "requirement": _text, "inconclusive": _expect}
_POSE = _list(_num(-1e38, 1e38), 6, 6)
STEP_SPEC: dict[str, dict[str, Callable[[Any], None]]] = {
    "open": {"open": _text, "target": _of("command", "stream"), "count": _num(1, 2000, integer=True)},
    "close": {"close": _text}, "abort": {"abort": _text},
    "request": {"request": _action, **_REQ, "poses": _list(_POSE),
                "tolerances": _list(_num(-1e38, 1e38)), "values": _list(_num(-2**31, 2**31 - 1, integer=True), 1, 1)},
    "raw": {"raw": _hex, "times": _num(1, 1 << 20, integer=True), "probe": _bool, **_REQ},
    "send": {"send": _hex, "times": _num(1, 1 << 20, integer=True), **_ON, "split": lambda x: _keys(x, _SPLIT, ("pieces",))},
    "burst": {"burst": lambda x: _list(_burst_item, 1, 255)(x), "times": _num(1, 1000, integer=True), **_ON},
    "stream": {"stream": _text, "rate": _num(0.1, 10000, ("profile",)), "duration": _num(0.01, 3600, ("stream_seconds",)),
               "trajectory": lambda x: _of("primer", "fixed")(x) if isinstance(x, str) else _list(_POSE, 1, 10000)(x),
               "background": _bool, "expect": _expect, "max_lost": _num(0, 1 << 30, integer=True), "backlog": _bool},
    "stop": {"stop": _text},
    "sleep": {"sleep": _num(0, 3600, ("stream_seconds", "time_out", "vision_time_out"))},
    "repeat": {"repeat": _num(1, 100000, integer=True), "steps": lambda x: None},  # steps: checked recursively
}
_COMMON = {"note": _text, "level": _of("MUST", "SHOULD", "MAY")}
_HEADER = {"format": _of(FORMAT), "id": _text, "title": _text, "clauses": _list(_text, 1, 20), "level": _of("MUST", "SHOULD"),
           "expect": _text, "description": _text, "requires": _list(_of("extension"), 0, 4),
           "deadline_s": _num(1, 86400), "steps": lambda x: None}


def _burst_item(x: Any) -> None:
    if not isinstance(x, dict) or "request" not in x:
        raise ValueError("a burst item is a request step, e.g. {\"request\": \"Pose\"}")
    _keys(x, {k: v for k, v in STEP_SPEC["request"].items() if k in ("request", "poses", "tolerances", "values", "expect", "note")})


def verb_of(step: dict[str, Any]) -> str:
    verbs = [k for k in step if k in STEP_SPEC]
    if len(verbs) != 1:
        what = f"several verbs {verbs}" if verbs else f"no verb (keys {sorted(step)})"
        raise ValueError(f"{what}; a step has exactly one of {', '.join(STEP_SPEC)}")
    return verbs[0]


@dataclass(frozen=True)
class Sequence:
    path: Path
    id: str
    title: str
    clauses: tuple[str, ...]
    level: Level
    expect: str
    steps: list[dict[str, Any]]
    requires: tuple[str, ...] = ()
    deadline_s: float | None = None

    @property
    def stem(self) -> str:
        return self.path.stem

    def budget_s(self, settings: Any) -> float:
        """The overall deadline: the file's, or 20 s + 4×time_out + every timed step."""
        if self.deadline_s is not None:
            return float(self.deadline_s)
        return 20.0 + 4 * settings.time_out_s + _timed(self.steps, settings)


def _timed(steps: list[dict[str, Any]], settings: Any) -> float:
    total = 0.0
    for step in steps:
        if "repeat" in step:
            total += step["repeat"] * _timed(step["steps"], settings)
        elif "sleep" in step:
            total += seconds(step["sleep"], settings)
        elif "stream" in step and "duration" in step:
            total += seconds(step["duration"], settings)
    return total


def seconds(value: Any, settings: Any) -> float:
    """A duration that may name a profile/suite value symbolically."""
    return float({"stream_seconds": settings.stream_seconds, "time_out": settings.time_out_s,
                  "vision_time_out": settings.profile.vision_time_out_ms / 1000}.get(value, value))


def load(path: str | Path) -> Sequence:
    """Read and validate one sequence file; raise :class:`SequenceError` naming the file and the step."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise SequenceError(f"{path}: cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise SequenceError(f"{path}: not JSON: {exc}") from None
    where = "header"
    try:
        if not isinstance(doc, dict):
            raise ValueError("a sequence file holds one JSON object")
        _keys(doc, _HEADER, ("format", "id", "title", "clauses", "level", "steps"))
        if not _SEQ_ID.match(doc["id"]):
            raise ValueError(f"field 'id': {doc['id']!r} must look like 'SEQ-S1' (SEQ- then capitals, digits, dashes)")
        bad = [c for c in doc["clauses"] if not _CLAUSE.match(c)]
        if bad:
            raise ValueError(f"field 'clauses': unknown clause IDs {bad}")
        opened: set[str] = set()
        streams: set[str] = set()
        where = "steps"
        _check_steps(doc["steps"], "steps", opened, streams)
    except _StepError as exc:
        raise SequenceError(f"{path}: {exc}") from None
    except ValueError as exc:
        raise SequenceError(f"{path}: {where}: {exc}") from None
    return Sequence(path, doc["id"], doc["title"], tuple(doc["clauses"]), Level(doc["level"]),
                    str(doc.get("expect") or doc.get("description") or doc["title"]), doc["steps"],
                    tuple(doc.get("requires", ())), doc.get("deadline_s"))


class _StepError(ValueError):
    pass


def _check_steps(steps: Any, where: str, opened: set[str], streams: set[str]) -> None:
    if not isinstance(steps, list) or not steps:
        raise _StepError(f"{where}: expected a non-empty list of steps")
    for i, step in enumerate(steps):
        path = f"{where}[{i}]"
        try:
            if not isinstance(step, dict):
                raise ValueError(f"a step is an object, not {step!r}")
            verb = verb_of(step)
            path += f" ({verb})"
            _keys(step, {**STEP_SPEC[verb], **_COMMON}, ("steps",) if verb == "repeat" else ())
            _check_names(step, verb, opened, streams)
        except ValueError as exc:
            raise _StepError(f"{path}: {exc}") from None
        if verb == "repeat":
            _check_steps(step["steps"], f"{path}.steps", opened, streams)


def _check_names(step: dict[str, Any], verb: str, opened: set[str], streams: set[str]) -> None:
    if verb == "open":
        opened.add(step["open"])
        return
    if verb == "raw" and step.get("probe"):
        data = hex_bytes(step["raw"], step.get("times", 1))
        need = 14 + data[7] * int.from_bytes(data[8:10], "big") if data[:4] == b"\xfe\xfe\x00\x01" and len(data) >= 12 else 0
        if len(data) < need <= 6389:
            raise ValueError(f"the bytes are an incomplete frame (its header announces {need} bytes, {len(data)} given): "
                             "a box waits for the rest and swallows the probe; complete the frame, or 'send' it and "
                             "judge on another connection")
    name = step.get(verb) if verb in ("close", "abort", "stream", "stop") else step.get("on", "command")
    if verb in ("sleep", "repeat"):
        return
    if name not in opened:
        raise ValueError(f"connection {name!r} is not opened by an earlier step (opened: {sorted(opened) or 'none'})")
    if verb == "stream":
        streams.add(name)
    if verb == "stop" and name not in streams:
        raise ValueError(f"no stream runs on {name!r}")
    if verb == "request" and "poses" in step and action_of(step["request"]) not in (Action.POSE, Action.REGISTER_POSE):
        raise ValueError("'poses' go with Pose or RegisterPose (use 'raw' for a malformed frame)")
    if verb == "request" and "tolerances" in step and action_of(step["request"]) is not Action.TOLERANCE:
        raise ValueError("'tolerances' go with Tolerance (use 'raw' for a malformed frame)")
    if verb == "request" and "values" in step and action_of(step["request"]) is not Action.PROG_IDX:
        raise ValueError("'values' go with ProgIdx (use 'raw' for a malformed frame)")


def shipped() -> list[Sequence]:
    return [load(p) for p in sorted(SHIPPED_DIR.glob("*.json")) if not p.name.endswith(".schema.json")]


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


DEFAULT_POSE = PrimerTrajectory().home


def frame_of(step: dict[str, Any], first_index: int) -> Frame:
    action = action_of(step["request"])
    if action in (Action.POSE, Action.REGISTER_POSE):
        return request(action, pose_blocks(step.get("poses", [DEFAULT_POSE]), first_index))
    if action is Action.TOLERANCE:
        return request(action, tolerance_blocks(step.get("tolerances", [0.5]), first_index))
    if action is Action.PROG_IDX:
        return request(action, value_blocks(step.get("values", [1]), first_index))
    return request(action)


def pieces_of(data: bytes, split: dict[str, Any]) -> list[bytes]:
    """R3: ``data`` cut as the split spec says (every byte, random 1-8 byte pieces, or given sizes)."""
    how = split["pieces"]
    if how == "bytes":
        sizes: Iterator[int] = iter([1] * len(data))
    elif how == "random":
        rng = random.Random(split.get("seed", 1))
        sizes = iter(lambda: rng.randint(1, 8), None)  # type: ignore[arg-type]
    else:
        sizes = iter(list(how) + [len(data)])
    out, pos = [], 0
    while pos < len(data):
        n = next(sizes)
        out.append(data[pos : pos + n])
        pos += n
    return out


def percentile(values: list[float], q: float) -> float:
    if not values:
        return math.nan
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, math.ceil(q / 100 * len(ordered)) - 1))]


def latency_figures(values: list[float]) -> dict[str, Any]:
    if not values:
        return {"count": 0}
    return {"count": len(values), "p50_ms": round(percentile(values, 50), 3), "p90_ms": round(percentile(values, 90), 3),
            "p99_ms": round(percentile(values, 99), 3), "max_ms": round(max(values), 3)}


# -- the pose stream (S6, T2) -----------------------------------------------------------------------


@dataclass
class StreamResult:
    """What a pose stream saw: answers matched to poses in order, and how it ended."""

    rate_hz: float
    time_out_s: float = 5.0
    sent: int = 0
    answered: int = 0
    latencies_ms: list[float] = field(default_factory=list)
    bad: Outcome | None = None  # the first answer that did not match the expectation
    bad_index: int = -1
    bad_sent: bytes = b""
    extra: int = 0  # answers beyond the poses sent (A1)
    ended: str = ""  # "", "closed", "reset", "malformed", "overdue", "blocked": why the stream stopped early
    ended_by: Outcome | None = None
    max_send_lag_ms: float = 0.0
    elapsed_s: float = 0.0

    @property
    def lost(self) -> int:
        return self.sent - self.answered

    @property
    def failed(self) -> bool:
        return bool(self.ended) or self.bad is not None or self.extra > 0

    def backlog(self) -> tuple[float, float, float] | None:
        """(first-quarter p50, last-quarter p50, threshold) in ms; None with fewer than 8 answers.

        T2 backlog: the last quarter's p50 above first p50 + max(20 ms, 3 × first p50)."""
        n = len(self.latencies_ms) // 4
        if n < 2:
            return None
        first, last = percentile(self.latencies_ms[:n], 50), percentile(self.latencies_ms[-n:], 50)
        return first, last, first + max(20.0, 3 * first)

    def figures(self) -> dict[str, Any]:
        out = {"rate_hz": self.rate_hz, "sent": self.sent, "answered": self.answered, "lost": self.lost,
               "extra_answers": self.extra, "ended": self.ended or "normally", "elapsed_s": round(self.elapsed_s, 3),
               "max_send_lag_ms": round(self.max_send_lag_ms, 3), "latency": latency_figures(self.latencies_ms)}
        b = self.backlog()
        if b is not None:
            out["backlog"] = {"first_quarter_p50_ms": round(b[0], 3), "last_quarter_p50_ms": round(b[1], 3),
                              "threshold_ms": round(b[2], 3)}
        return out


def trajectory_poses(kind: Any, rate_hz: float, duration_s: float | None) -> Callable[[int], tuple[float, ...]]:
    """Pose number i of a stream: along the primer trajectory, fixed, or cycling through a given list."""
    if isinstance(kind, list):
        return lambda i: tuple(kind[i % len(kind)])
    if kind == "fixed":
        return lambda i: DEFAULT_POSE
    path = PrimerTrajectory(duration=max(0.5, duration_s or 2.0))
    return lambda i: path.pose_at((i / rate_hz) % path.duration)


class PoseStream:
    """Poses on a fixed clock from a background thread, answers read as they come (pipelined).

    Send times come from a monotonic schedule (``t0 + i/rate``), not from sleeps, so
    they do not drift. One thread both sends and reads, so the connection is never
    shared; the answer k is matched to pose k (A1: in order). The stream ends after
    ``duration_s`` (None: until :meth:`stop`), or early when the box closes, sends
    malformed bytes, or leaves a pose unanswered for longer than ``time_out_s``.
    """

    def __init__(self, conn: TcpConnection, rate_hz: float, duration_s: float | None, time_out_s: float,
                 poses: Callable[[int], tuple[float, ...]] | None = None, expect: Expect | None = None,
                 first_index: int = 0) -> None:
        self.conn, self.rate_hz, self.duration_s, self.time_out_s = conn, rate_hz, duration_s, time_out_s
        self.poses = poses or trajectory_poses("primer", rate_hz, duration_s)
        self.expect = expect or answered(Action.POSE, [0])
        self.first_index = first_index
        self.result = StreamResult(rate_hz, time_out_s)
        self._sent_at: list[float] = []
        self._frames: list[bytes] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"isight-pose-stream-{conn.label}", daemon=True)

    def start(self) -> PoseStream:
        self._thread.start()
        return self

    def stop(self) -> StreamResult:
        """Stop sending, wait (bounded by time_out) for the answers still due, and return the result."""
        self._stop.set()
        return self.wait()

    def wait(self, timeout_s: float | None = None) -> StreamResult:
        limit = timeout_s if timeout_s is not None else (self.duration_s or 0) + self.time_out_s + 2.0
        self._thread.join(limit)
        if self._thread.is_alive():  # never expected: every wait inside is bounded
            self._stop.set()
            self._thread.join(self.time_out_s + 2.0)
        return self.result

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _run(self) -> None:
        r, period = self.result, 1.0 / self.rate_hz
        count = None if self.duration_s is None else max(1, round(self.duration_s * self.rate_hz))
        codec, label = self.conn.codec, self.conn.label
        t0 = time.monotonic()
        try:
            while not self._stop.is_set() and (count is None or r.sent < count):
                due = t0 + r.sent * period
                if not self._read_until(due):
                    return
                pose = self.poses(r.sent)
                data = codec.encode(request(Action.POSE, pose_blocks([pose], self.first_index)))
                now = time.monotonic()
                r.max_send_lag_ms = max(r.max_send_lag_ms, (now - due) * 1000)
                self._sent_at.append(now)
                self._frames.append(data)
                r.sent += 1
                if not self.conn.send(data, f"{label}: pose {r.sent}"):
                    if self.conn.closed_by_peer is None:
                        r.ended = "blocked"  # the send did not complete within time_out
                    else:
                        self._end(self.conn.closed_by_peer)
                    return
            while r.answered < r.sent and not r.ended:  # the answers still due, bounded by time_out
                if not self._read_until(time.monotonic() + 0.05):
                    return
        finally:
            r.elapsed_s = time.monotonic() - t0

    def _read_until(self, until: float) -> bool:
        """Read answers until ``until``; False when the stream must end."""
        r = self.result
        while True:
            now = time.monotonic()
            if r.answered < r.sent and now - self._sent_at[r.answered] > self.time_out_s:
                r.ended = "overdue"
                return False
            if now >= until:
                return True
            outcome = self.conn.next_outcome(max(until - now, 0.0002))
            if isinstance(outcome, Silence):
                continue
            if not isinstance(outcome, Answer):
                self._end(outcome)
                return False
            k = r.answered
            if k >= r.sent:
                r.extra += 1
                if r.bad is None:
                    r.bad, r.bad_index = outcome, k
                return False
            r.latencies_ms.append((time.monotonic() - self._sent_at[k]) * 1000)
            if r.bad is None and not self.expect.matches(outcome):
                r.bad, r.bad_index, r.bad_sent = outcome, k, self._frames[k]
            r.answered += 1

    def _end(self, outcome: Outcome) -> None:
        r = self.result
        r.ended_by = outcome
        r.ended = "malformed" if isinstance(outcome, Malformed) else "reset" if getattr(outcome, "reset", False) else "closed"


def judge_stream(r: StreamResult, level: Level, what: str, max_lost: int = 0, backlog: bool = False) -> None:
    """Raise the verdict for a stream: a wrong answer, lost answers, or (``backlog``) latency that grew."""
    if r.bad is not None and r.extra == 0:
        check(r.bad, answered(Action.POSE, [0]), level, f"{what}: pose {r.bad_index + 1} is answered 0000",
              sent=r.bad_sent)
    if r.extra:
        raise fail(level, f"A1/{what}: exactly one answer per pose", f"{r.sent} answers",
                   f"{r.extra} answer(s) more than poses sent")
    if r.ended == "malformed" and r.ended_by is not None:
        check(r.ended_by, answered(Action.POSE), level, f"{what}: every pose is answered with a well-formed frame")
    if r.lost > max_lost:
        why = {"overdue": f"pose {r.answered + 1} got no answer within time_out ({r.time_out_s * 1000:.0f} ms)",
               "closed": "the box closed the connection", "reset": "the box reset the connection",
               "blocked": "the box stopped reading (a send did not complete within time_out)"}.get(r.ended, "")
        raise fail(level, f"{what}: every pose is answered (none lost)", f"{r.sent} answers" + (
            f" (at most {max_lost} lost)" if max_lost else ""), f"{r.answered} answers, {r.lost} lost" + (f": {why}" if why else ""))
    b = r.backlog() if backlog else None
    if b is not None and b[1] > b[2]:
        raise fail(level, f"{what}: answer latency does not grow over the run (backlog)",
                   f"last-quarter p50 ≤ {b[2]:.1f} ms (first-quarter p50 {b[0]:.1f} ms + max(20 ms, 3×))",
                   f"backlog: last-quarter p50 {b[1]:.1f} ms")


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
        check(outcome, expect, level, requirement, sent=sent)

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
                           "the connection is accepted within time_out", str(exc)) from None
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
        frame = frame_of(step, self.isight.profile.first_index)
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
        frames = [frame_of(item, self.isight.profile.first_index) for item in items]
        data = b"".join(conn.codec.encode(f) for f in frames)
        self.isight.last_sent = data
        start = time.monotonic()
        conn.send(data, step.get("note") or f"{len(frames)} requests in one segment (R4)")
        for k, (item, frame) in enumerate(zip(items, frames)):
            wait = self._wait(None, path)
            outcome = conn.next_outcome(wait, since=start)
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
                            expectation(step.get("expect"), Action.POSE), self.isight.profile.first_index)
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
        what = f"{', '.join(self.seq.clauses)}: {self.seq.title}, pose stream of {where}"
        if level is Level.MAY:
            if result.failed or result.lost > step.get("max_lost", 0):
                self.isight.inform(f"{where}: {result.figures()}")
            return
        judge_stream(result, level, what, step.get("max_lost", 0), step.get("backlog", False))

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
        return Action(data[5]) if len(data) > 5 else None
    except ValueError:
        return None


def _summary(step: dict[str, Any], verb: str) -> str:
    value = step[verb]
    on = f" on {step['on']}" if "on" in step else ""
    return f"{verb} {value if not isinstance(value, list) else f'{len(value)} items'}{on}"


def run_sequence(isight: Any, seq: Sequence) -> None:
    SequenceRunner(isight, seq).run()
