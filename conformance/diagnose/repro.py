"""A root cause's minimal repro as ``rootcause-N.json`` (isight-vectors-1), and its judgement on ``replay``.

The file holds the fewest frames that show the defect alone, in ``tcId`` order, to be sent on ONE
fresh connection; each test carries ``expect``, the set of legal answers to its frame (a valid
request: exactly one answer, its action echoed, an error code among ``errorCodes``; a parse
error: anything but a 0000 answer with its action, silence and a close included). The top-level
``rootCause`` names the root cause (id, title, clauses, mechanism). ``replay`` sends the frames
and prints per root cause **fixed** (every answer legal) or **still present** (and what is not).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..evidence.vectors_file import SCHEMA, frame_to_dict
from ..harness.target import Target
from ..model.verdicts import RootCause
from ..protocol import Profile, TransferType, Transport, codec_for
from ..protocol.errors import ProtocolError
from .experiments import Prober
from .hypotheses import Expect

NOTE = ("A root cause's minimal repro: send every test's frame, in tcId order, on ONE fresh connection; each "
        "test's 'expect' is the set of legal answers to its frame ('replay' judges them: fixed / still present)")


def file_name(cause_id: str) -> str:
    """``RC3`` -> ``rootcause-3.json``."""
    return f"rootcause-{cause_id.removeprefix('RC')}.json"


def repro_entry(cause_id: str, frames: Sequence[tuple[bytes, Expect]], one_write: bool = False) -> dict[str, Any]:
    """What a root cause's diagnosis keeps of its repro (summary.json shows it); ``one_write``: the frames go
    in one write (the defect shows only when they arrive together)."""
    return {"file": file_name(cause_id), "one_write": one_write,
            "frames": [{"hex": f.hex(), "expect": e.to_dict()} for f, e in frames]}


def document(cause: RootCause, profile: Profile) -> dict[str, Any] | None:
    """The isight-vectors-1 document of a root cause's repro (None: it has none)."""
    repro = (cause.diagnosis or {}).get("repro")
    if not repro or not repro.get("frames"):
        return None
    codec = codec_for(profile)
    clauses = [c for c in cause.clauses if c[:1] in "FBASTRE" and c[1:].isdigit()] or ["A1"]
    tests = []
    for n, item in enumerate(repro["frames"], 1):
        data, expect = bytes.fromhex(item["hex"]), Expect.from_dict(item["expect"])
        test: dict[str, Any] = {"tcId": n, "comment": f"{cause.id} frame {n}: {_say(expect)}", "clauses": clauses,
                                "flags": ["RootCause"], "result": expect.kind, "hex": data.hex(), "expect": expect.to_dict()}
        if expect.kind == "valid":
            try:
                test["frame"] = frame_to_dict(codec.parse(data, Transport.TCP, TransferType.ROBOT_TO_BOX))
            except (ProtocolError, ValueError):
                test["result"] = "invalid"
        tests.append(test)
    return {"schema": SCHEMA, "description": f"{cause.id}: {cause.title}", "numberOfTests": len(tests),
            "notes": {"RootCause": NOTE},
            "rootCause": {"id": cause.id, "title": cause.title, "clauses": list(cause.clauses), "kind": cause.kind,
                          "confirmed": bool(cause.confirmed), "oneWrite": bool(repro.get("one_write"))},
            "testGroups": [{"transport": "tcp", "crc": profile.crc if profile.crc in _CRCS else "modbus",
                            "direction": "robot-to-box", "profile": {"firstIndex": profile.first_index},
                            "tests": tests}]}


_CRCS = ("modbus", "xmodem", "kermit", "crc-16", "x-25", "crc-ccitt-false")


def _say(expect: Expect) -> str:
    if expect.kind == "valid":
        return (f"a valid request: exactly one answer, action {expect.action:02X} echoed, error "
                + " or ".join(f"{c:04X}" for c in expect.codes))
    return f"a parse error (action {expect.action:02X}): never answered 0000"


def write_repros(report_dir: Path, causes: Sequence[RootCause], profile: Profile) -> list[Path]:
    """``rootcause-N.json`` for every root cause with a repro, written atomically."""
    written = []
    for cause in causes:
        doc = document(cause, profile)
        if doc is None:
            continue
        report_dir.mkdir(parents=True, exist_ok=True)
        path = report_dir / file_name(cause.id)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n", encoding="utf-8")
        tmp.replace(path)
        written.append(path)
    return written


# -- replay ------------------------------------------------------------------------------------------------
def is_repro(path: str | Path) -> bool:
    """Whether a file is a root cause's repro (has a top-level ``rootCause``)."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and isinstance(doc.get("rootCause"), dict)


@dataclass(frozen=True)
class Judged:
    name: str  # RC1 and its title
    status: str  # "fixed" | "still present" | "could not tell"
    problems: tuple[str, ...] = ()

    def line(self) -> str:
        tail = f" -- {'; '.join(self.problems)}" if self.problems else ""
        return f"{self.status:<14} {self.name}{tail}"


def load(path: str | Path) -> tuple[str, list[tuple[bytes, Expect]], bool]:
    """A repro's name (id: title), its frames with their legal answers, and whether they go in one write."""
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    rc = doc["rootCause"]
    tests = sorted((t for g in doc["testGroups"] for t in g["tests"]), key=lambda t: t["tcId"])
    frames = [(bytes.fromhex(t["hex"]), Expect.from_dict(t["expect"])) for t in tests]
    return f"{rc['id']}: {rc['title']}", frames, bool(rc.get("oneWrite"))


def judge(path: str | Path, target: Target, profile: Profile, time_out_s: float) -> Judged:
    """Send the repro on one fresh connection and judge every answer against its legal set."""
    name, frames, one_write = load(path)
    deadline = time.monotonic() + time_out_s * (len(frames) + 1) + 5
    prober = Prober(target, profile, time_out_s, deadline)
    ex = prober.exchange([f for f, _ in frames], quiet=[e.kind == "invalid" for _, e in frames], together=one_write)
    if ex is None or not ex.reached:
        return Judged(name, "could not tell", (prober.unreachable or "no connection",))
    if one_write:
        answers = list(ex.reading(0).answers)
        readings = [e.take(answers) for _, e in frames]
        extra = [f"{len(answers)} answer(s) more than the requests"] if answers else []
    else:
        readings, extra = [ex.reading(i) for i in range(len(frames))], []
    problems = tuple(f"frame {i + 1}: {why}" for i, (_, e) in enumerate(frames) if (why := e.broken_by(readings[i])))
    return Judged(name, "still present" if problems or extra else "fixed", problems + tuple(extra))


def replay_repros(paths: Sequence[str | Path], target: Target, profile: Profile, time_out_s: float,
                  log: Callable[[str], None] = print) -> int:
    """Judge every repro file; 0 when every root cause is fixed, else 1."""
    results = [judge(p, target, profile, time_out_s) for p in paths]
    for r in results:
        log("  " + r.line())
    fixed = sum(r.status == "fixed" for r in results)
    log(f"replay: {len(results)} root cause(s): {fixed} fixed, {len(results) - fixed} still present or not judged")
    return 0 if fixed == len(results) else 1
