"""Evidence of a fuzz failure: an ``isight-vectors-1`` file and a pcapng of the failing example.

The vector file holds the (shrunk) bytes as one test per case, with the clauses it
breaks, ``result`` as a conforming receiver must read the bytes (``invalid`` for a
malformed frame, ``valid`` with its ``frame`` for a well-formed request the box
mishandled) and a ``comment`` saying what the box did. ``isight-conformance replay
FILE`` resends it. The pcap is synthesised from the socket transcript of the
evidence run (a fresh connection: the bytes, the probe, the liveness check) with
:func:`~conformance.evidence.pcap.write_transcript`. A failing session of the state
machine (:mod:`.session_runner`) is also written as an ``isight-sequence-1`` file.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..evidence.pcap import write_transcript
from ..evidence.vectors_file import frame_to_dict, write
from ..harness.transcript import Transcript
from ..protocol import Frame, Profile, ProtocolError, TransferType, Transport, parse_frame
from ..suite.record import CLAUSE_ID
from .last_words import LastWords
from .strategies import FuzzCase


@dataclass
class Failure:
    """One distinct failure a campaign found."""

    number: int
    kind: str  # "oracle" (shrunk by hypothesis), "death" (R2), "context" (only on a reused connection), "stateful"
    clauses: list[str]
    message: str  # the requirement and what the box did
    cases: list[FuzzCase] = field(default_factory=list)
    shrunk: bool = False
    confirmed: bool = True
    vector: Path | None = None
    pcap: Path | None = None
    sequence: Path | None = None
    steps: list[str] = field(default_factory=list)  # stateful: the (shrunk) rule sequence
    found_after: int = 0  # examples generated before it was found
    found_s: float = 0.0  # seconds into the campaign when it was found
    keys: list[str] = field(default_factory=list)  # the oracle's finding keys (clause/rule/action/what)
    new_connections: list[bool] = field(default_factory=list)  # a death's sequence: which case opened a connection
    last_words: LastWords | None = None  # what the box that died wrote (fuzz --restart-cmd keeps it)

    @property
    def malformed_answer(self) -> bool:
        """The box's answer itself was not a conforming frame (F1-F3, A2, E3)."""
        return bool(self.keys) and self.keys[0].startswith("answer/")

    @property
    def hex(self) -> str:
        return " ".join(c.wire.hex() for c in self.cases)

    def to_dict(self) -> dict[str, Any]:
        return {
            "number": self.number, "kind": self.kind, "clauses": self.clauses, "message": self.message,
            "cases": [{"kind": c.kind, "note": c.note, "transport": c.transport.value, "eof": c.eof,
                       "hex": c.wire.hex()} for c in self.cases],
            "shrunk": self.shrunk, "confirmed": self.confirmed, "steps": self.steps, "found_after": self.found_after,
            "found_s": round(self.found_s, 3), "keys": self.keys,
            "vector": str(self.vector) if self.vector else None, "pcap": str(self.pcap) if self.pcap else None,
            "sequence": str(self.sequence) if self.sequence else None,
            "last_words": self.last_words.to_dict() if self.last_words is not None else None,
        }


def clauses_of(case: FuzzCase, extra: Sequence[str] = ()) -> list[str]:
    """The case's clauses for a vector: the decoder's first, then the strategy's, then ``extra``."""
    out: list[str] = []
    for c in (case.first_clause, case.clause, *(e.clause for e in case.expects), *extra):
        for part in c.split("/"):
            if part and CLAUSE_ID.match(part) and part not in out:
                out.append(part)
    return out or ["A1"]


def _frame(case: FuzzCase, profile: Profile) -> Frame | None:
    """The request the bytes are, when they are exactly one well-formed frame."""
    if case.filler or case.eof:
        return None
    try:
        return parse_frame(case.data, profile, case.transport, TransferType.ROBOT_TO_BOX)
    except ProtocolError:
        return None


def vector_entry(tc_id: int, case: FuzzCase, profile: Profile, comment: str, clauses: Sequence[str]) -> dict[str, Any]:
    frame = _frame(case, profile) if case.valid else None
    entry: dict[str, Any] = {
        "tcId": tc_id,
        "comment": comment,
        "clauses": list(clauses),
        "flags": [],
        "result": "valid" if frame is not None else "invalid",
        "hex": case.wire.hex(),
    }
    if frame is not None:
        entry["frame"] = frame_to_dict(frame)
    return entry


def write_vectors(path: Path, failure: Failure, profile: Profile, description: str) -> Path:
    """The failure's cases as an ``isight-vectors-1`` file (one group per transport)."""
    groups: dict[Transport, dict[str, Any]] = {}
    for i, case in enumerate(failure.cases, 1):
        group = groups.get(case.transport)
        if group is None:
            group = groups[case.transport] = {
                "transport": case.transport.value,
                "crc": profile.crc,
                "direction": "robot-to-box",
                "profile": {"firstIndex": profile.first_index, "crcByteOrder": profile.crc_byte_order},
                "tests": [],
            }
        where = f" (case {i} of {len(failure.cases)}, in this order on one connection)" if failure.kind == "context" else ""
        flags = _sequence_flags(failure, i - 1)
        if flags:
            where = f" (case {i} of {len(failure.cases)} of the sequence that kills the box, in this order)"
        comment = f"fuzz failure {failure.number} ({failure.kind}){where}: {case.describe()}. {failure.message}"
        entry = vector_entry(len(group["tests"]) + 1, case, profile, comment, clauses_of(case, failure.clauses))
        entry["flags"] = flags + split_flags(case) + (["BoxLastWords"] if failure.last_words is not None else [])
        group["tests"].append(entry)
    path.parent.mkdir(parents=True, exist_ok=True)
    notes: dict[str, str] = {}
    for flag in sorted({f for g in groups.values() for t in g["tests"] for f in t["flags"]}):
        notes[flag] = SEQUENCE_NOTES.get(flag) or _split_note(flag)
    if failure.last_words is not None and groups:
        words = failure.last_words
        notes["BoxLastWords"] = f"{words.summary()}. What it wrote last:\n{words.shown_tail()}"
    if profile.byte_order != "big" or profile.float_byte_order != "big":
        description += (f" Profile: byte order {profile.byte_order}, float byte order {profile.float_byte_order} "
                        "(the vectors are in that order).")
    write(path, list(groups.values()), notes, description)
    return path


#: Flags of a death's sequence (``replay`` sends a file's KillSequence vectors in order, liveness after the last).
SEQUENCE_NOTES = {
    "KillSequence": "one step of a sequence that kills the box: replay sends the file's steps in order and checks "
                    "liveness (R2) after the last",
    "NewConnection": "this step of the sequence goes on a new connection (the ones before it on the previous one)",
}


def split_flags(case: FuzzCase) -> list[str]:
    """R3: how a split case is written (``SplitAt<offset>``, ``PauseMs<ms>``); ``replay`` writes it so again."""
    if not case.splits:
        return []
    return [f"SplitAt{c}" for c in case.splits] + [f"PauseMs{round(case.gap_s * 1000)}"]


def splits_of(flags: Sequence[str]) -> tuple[tuple[int, ...], float]:
    """The inverse of :func:`split_flags`: (cut offsets, pause in seconds)."""
    cuts = tuple(int(f[7:]) for f in flags if f.startswith("SplitAt") and f[7:].isdigit())
    gap = next((int(f[7:]) / 1000 for f in flags if f.startswith("PauseMs") and f[7:].isdigit()), 0.0)
    return cuts, gap


def _split_note(flag: str) -> str:
    if flag.startswith("SplitAt"):
        return f"R3: the bytes are written in pieces, one cut at offset {flag[7:]}"
    return f"R3: a pause of {flag[7:]} ms between the pieces"


def _sequence_flags(failure: Failure, i: int) -> list[str]:
    if failure.kind != "death" or len(failure.cases) < 2:
        return []
    new = failure.new_connections[i] if i < len(failure.new_connections) else i == 0
    return ["KillSequence"] + (["NewConnection"] if new or i == 0 else [])


def write_pcap(transcript: Transcript, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_transcript(transcript, path)


def write_summary(path: Path, summary: dict[str, Any]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(summary, indent=1, default=str) + "\n", encoding="utf-8")
    tmp.replace(path)
    return path


def write_sequence(path: Path, number: int, failure: Failure, steps: list[dict[str, Any]]) -> Path:
    """A failing session as an ``isight-sequence-1`` file (``run --sequence FILE``)."""
    doc = {
        "format": "isight-sequence-1",
        "id": f"SEQ-FUZZ-{number:03d}",
        "title": f"Fuzz session failure {number} [{', '.join(failure.clauses)}], {len(failure.steps)} steps",
        "description": failure.message,
        "clauses": failure.clauses or ["A1"],
        "level": "MUST",
        "expect": "every answer as the fuzz oracle requires (see the notes of each step)",
        "steps": steps,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return path
