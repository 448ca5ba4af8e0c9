"""``isight-conformance replay FILE``: resend the vectors of ``isight-vectors-1`` files to a box.

Every robot→box vector is sent as it is, on a fresh connection (or, with
``one_connection``, all on one connection in file order, which is how a fuzz failure
that only happens after earlier cases reproduces), followed by a probe; a vector
that leaves a frame open (a truncated frame: "the stream ends after it") is sent and
the stream ended instead. UDP vectors go to the UDP target as one datagram each. What
the box does is judged by the fuzz oracle — the same expectations the fuzzer uses,
computed from the bytes with the run's profile (a vector's ``result`` is what a
conforming receiver decides; the oracle says what a conforming *box* may answer) —
and a liveness check on a fresh connection follows every vector (R2).

Skipped: box→robot vectors (for robot-side decoders), UDP vectors without a UDP
target, and vectors whose group profile (first index of a frame with blocks, UDP
CRC) is not the run's. Works on the golden vector files and on the files ``fuzz``
writes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ..evidence.vectors_file import Vector, load
from ..harness.liveness import responsive
from ..harness.target import Target
from ..harness.transcript import Transcript
from ..model.verdicts import Verdict
from ..protocol import Profile, TransferType, Transport, peek_header
from .executor import Executor
from .failure_files import splits_of
from .oracle import expectations
from .strategies import FuzzCase


@dataclass
class Replayed:
    vector: Vector
    status: str  # OK, FAIL, NON-STRICT, SKIP, NOT RUN
    did: str = ""  # what the box did
    why: str = ""  # the oracle's findings, or why the vector was skipped

    @property
    def failing(self) -> bool:
        return self.status == "FAIL"

    def line(self) -> str:
        clauses = ",".join(self.vector.clauses[:4])
        head = f"{self.status:<10} {self.vector.name:<32} {self.vector.result:<10} [{clauses}]"
        body = self.did if self.status != "SKIP" else ""
        tail = f" -- {self.why}" if self.why else ""
        return f"{head} {body}{tail}".rstrip()


def _skip_reason(v: Vector, profile: Profile, udp_target: Target | None) -> str:
    if v.direction is not TransferType.ROBOT_TO_BOX:
        return "a box→robot vector: for robot-side decoders, not sent to a box"
    if v.transport is Transport.UDP and udp_target is None:
        return "UDP vector and no --udp-target"
    head = peek_header(v.data)
    has_blocks = head is not None and head.block_count > 0
    if has_blocks and v.profile.first_index != profile.first_index:
        return f"written for first index {v.profile.first_index}; this run uses --first-index {profile.first_index}"
    if v.transport is Transport.UDP and (v.profile.crc, v.profile.crc_byte_order) != (profile.crc, profile.crc_byte_order):
        return (f"written for CRC {v.profile.crc} ({v.profile.crc_byte_order}); this run uses --crc {profile.crc} "
                f"({profile.crc_byte_order})")
    return ""


def case_of(v: Vector, profile: Profile, extension: bool) -> FuzzCase:
    """The vector as a fuzz case: its bytes and the oracle's expectations (end of stream if it leaves a frame open)."""
    filler, expects = expectations(v.data, profile, v.transport, extension)
    eof = bool(filler)
    if eof:
        filler, expects = expectations(v.data, profile, v.transport, extension, eof=True)
    clause = v.clauses[0] if v.clauses else ""
    splits, gap = splits_of(v.flags)
    return FuzzCase(f"vector:{v.result}", clause, v.data, f"{v.name}: {v.comment[:100]}", v.transport, eof, filler,
                    expects, splits, gap)


def replay(
    vectors: Sequence[Vector],
    target: Target,
    profile: Profile,
    *,
    udp_target: Target | None = None,
    extension: bool = True,
    one_connection: bool = False,
    settle_s: float = 0.0,
    transcript: Transcript | None = None,
    log: Callable[[str], None] | None = None,
) -> list[Replayed]:
    """Send each vector and judge what the box does now (stops sending once the box is dead)."""
    tr = transcript if transcript is not None else Transcript(case_id="REPLAY")
    ex = Executor(target, profile, tr, udp_target=udp_target, extension=extension, liveness_every=1,
                  settle_s=settle_s)
    ex.isolate = not one_connection
    ex.settle = settle_s > 0
    out: list[Replayed] = []
    dead = ""
    try:
        for v in vectors:
            reason = _skip_reason(v, profile, udp_target)
            if reason or dead:
                item = Replayed(v, "SKIP" if reason else "NOT RUN", why=reason or dead)
            else:
                _sequence_step(ex, v, vectors, one_connection)
                result = ex.run(case_of(v, profile, extension), f"vector {v.name}")
                judgement = result.judgement
                status = {Verdict.FAIL: "FAIL", Verdict.NON_STRICT: "NON-STRICT"}.get(judgement.verdict, "OK")
                why = judgement.describe() if judgement.findings else ""
                if result.liveness is not None and not responsive(result.liveness):
                    status = "FAIL"
                    dead = f"the box died after vector {v.name} (R2)"
                    why = "; ".join(x for x in (why, f"R2: a fresh connection then {result.liveness.describe()}") if x)
                item = Replayed(v, status, result.observed(), why)
            out.append(item)
            if log is not None:
                log(item.line())
    finally:
        ex.close()
    return out


def _sequence_step(ex: Executor, v: Vector, vectors: Sequence[Vector], one_connection: bool) -> None:
    """A step of a sequence that killed the box (flag KillSequence): on the connection of the step before it unless
    it opened a new one, and liveness checked only after the file's last step."""
    if "KillSequence" not in v.flags:
        ex.isolate, ex.liveness_every = not one_connection, 1
        return
    rest = [w for w in vectors if w.file == v.file and "KillSequence" in w.flags]
    ex.isolate = False
    if "NewConnection" in v.flags:
        ex.drop_connection()
    ex.liveness_every = 1 if v is rest[-1] else 10**9


def load_files(paths: Sequence[str | Path], only: Sequence[int] = ()) -> list[Vector]:
    """Every vector of the files (``only``: these tcIds)."""
    found = [v for p in paths for v in load(p)]
    return [v for v in found if not only or v.tc_id in only]


def summary_line(results: Sequence[Replayed]) -> str:
    counts: dict[str, int] = {}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    parts = ", ".join(f"{n} {s}" for s, n in sorted(counts.items(), key=lambda kv: -kv[1]))
    return f"replay: {len(results)} vectors: {parts or 'none'}"
