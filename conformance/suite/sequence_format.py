"""The ``isight-sequence-1`` format: loading and validating scripted sequence files.

A sequence is data: a header (``id``, ``title``, ``clauses``, ``level``) and a list
of steps, each an object whose *verb* key says what it does (``open``, ``request``,
``stream``, ``repeat`` …; ``vectors/sequences/README.md`` documents them). The
loader validates a file itself, with messages naming the file and the step (no
jsonschema at run time); :mod:`.sequence` runs what it loads.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..evidence.vectors_file import REPO_VECTORS
from ..model.verdicts import Level
from ..protocol import DEFAULT_PROFILE, HEADER_LEN, MAX_FRAME_LEN, Action, codec_for
from .case_judge import CLOSED, NOT_OK, SILENCE, Expect
from .record import CLAUSE_ID, CaseRecord, record

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
    """A loaded sequence file: its case record (the suite's one record) and its steps."""

    path: Path
    record: CaseRecord
    steps: list[dict[str, Any]]
    requires: tuple[str, ...] = ()
    deadline_s: float | None = None

    @property
    def id(self) -> str:
        return self.record.id

    @property
    def title(self) -> str:
        return self.record.title

    @property
    def clauses(self) -> tuple[str, ...]:
        return self.record.clauses

    @property
    def level(self) -> Level:
        return self.record.level

    @property
    def expect(self) -> str:
        return self.record.expect

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
                  "vision_time_out": settings.profile.vision_time_out_s}.get(value, value))


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
        bad = [c for c in doc["clauses"] if not CLAUSE_ID.match(c)]
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
    requires = tuple(doc.get("requires", ()))
    case = record(doc["id"], doc["clauses"], doc["level"], doc["title"],
                  str(doc.get("expect") or doc.get("description") or doc["title"]),
                  needs=("extension",) if "extension" in requires else ())
    return Sequence(path, case, doc["steps"], requires, doc.get("deadline_s"))


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


def _announced_length(data: bytes) -> int:
    """The length a frame header at the start of ``data`` announces, read in the byte order its
    version field reads 1 in (either profile's); 0 when ``data`` does not start with a header."""
    if len(data) >= HEADER_LEN:
        for codec in (codec_for(DEFAULT_PROFILE), codec_for(DEFAULT_PROFILE.swapped(header=True))):
            if data[:4] == codec.start:
                return codec.frame_length(data)
    return 0


def _check_names(step: dict[str, Any], verb: str, opened: set[str], streams: set[str]) -> None:
    if verb == "open":
        opened.add(step["open"])
        return
    if verb == "raw" and step.get("probe"):
        data = hex_bytes(step["raw"], step.get("times", 1))
        need = _announced_length(data)
        if len(data) < need <= MAX_FRAME_LEN:
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
