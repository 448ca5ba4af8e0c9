"""After a case, a fresh connection left unanswered: a death, or a stall of the whole box? (issue 34, item 3)

The session concludes a death (R2, S5) when a NONE on a fresh connection goes unanswered for
time_out after a case. A box whose whole loop blocks for a while meets the same silence, then
answers again: before the death is recorded the box is given :data:`COME_BACK` time_outs more
on another fresh connection. Answered, the silence was a **box stall** (T1, S4): it is reported
with when it began (after which case and bytes, how many writes the session had made), how long
it lasted (at most) and who it held, as a FAIL of the stall (signature :data:`STALL`, its own
root cause: :mod:`conformance.engine.box_events`), never as the case's verdict on its input.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..harness.client import Answer, Malformed, Outcome
from ..harness.liveness import check_alive, responsive
from ..harness.target import Target
from ..harness.transcript import Kind, Transcript
from ..model.case_verdicts import CaseVerdict
from ..model.signature import Sig, Signature
from ..model.verdicts import Verdict
from ..protocol import Profile
from . import stall_point

#: the time_outs a box that went silent is given to answer a fresh connection again (then it is dead)
COME_BACK = 2.0
#: the signature of a stall's verdict (the fuzz campaign's too): grouped with nothing, its own root cause
STALL = Signature(Sig.CASE, "box-stall", "T1")
STALL_TEXT = "T1/S4: every connection, a fresh one included, is answered within time_out"


@dataclass(frozen=True)
class Stall:
    case_id: str
    after: str  # the last bytes the case sent (hex, cut short)
    writes: int  # writes the session had made to the box by then
    lasted_s: float  # from the case's last answer (or first write) to the answer on the fresh connection
    affected: str
    at: int | None = None  # the action of the first request the box left unanswered (:mod:`.stall_point`)

    def describe(self) -> str:
        at = "" if self.at is None else f" on {stall_point.word(self.at)} (the only request it left unanswered)"
        return (f"The whole box stalled for about {self.lasted_s:.1f} s{at}, once: case {self.case_id} met it (after "
                f"{self.after}; the session's write {self.writes}); {self.affected}")

    def to_dict(self) -> dict[str, object]:
        return {"case": self.case_id, "after": self.after, "writes": self.writes, "lasted_s": round(self.lasted_s, 2),
                "affected": self.affected, "example": None, "at": self.at}


def _began(transcript: Transcript, before: float) -> float:
    """When the box was last heard in the case before ``before`` (its last answer), else the case's first write
    (time.time() seconds)."""
    heard = [e.t for e in transcript.events if e.kind == Kind.RECV and e.t < before]
    sent = [e.t for e in transcript.events if e.kind == Kind.SEND and e.t < before]
    return max(heard) if heard else min(sent) if sent else before


def _after(transcript: Transcript, last_sent: bytes, before: float) -> str:
    """The bytes the case last wrote before the silence (hex, cut short)."""
    data = last_sent or next((e.data for e in reversed(transcript.events) if e.kind == Kind.SEND and e.t < before
                              and e.data), b"")
    return data[:16].hex(" ") + (" …" if len(data) > 16 else "") if data else "its first bytes"


def _at(transcript: Transcript, before: float) -> int | None:
    """The first request of the case's last write before ``before`` that no answer after it on its connection
    covers (:func:`.stall_point.first_unanswered`)."""
    write = next((e for e in reversed(transcript.events) if e.kind == Kind.SEND and e.t < before and e.data), None)
    if write is None:
        return None
    heard = b"".join(e.data for e in transcript.events if e.kind == Kind.RECV and e.conn == write.conn
                     and write.t <= e.t < before)
    return stall_point.first_unanswered(write.data, heard)


def look_again(transcript: Transcript, target: Target, profile: Profile, case_id: str, last_sent: bytes,
               writes: int, ended: float) -> Stall | None:
    """Another fresh connection, given COME_BACK time_outs: answered, the stall it was; None: still silent."""
    time_out = profile.time_out_s
    began = _began(transcript, ended)  # the case's own events, not the fresh connections'
    outcome = check_alive(transcript, target, profile, time_out_s=COME_BACK * time_out, label="stall or death?",
                          note="a NONE on another fresh connection: does the box come back (a stall) or not (a death)?")
    if not responsive(outcome) or not isinstance(outcome, (Answer, Malformed)):
        return None
    after = _after(transcript, last_sent, ended)
    held = (f"the case's connection and a fresh connection (unanswered for {time_out:.1f} s) were held; another "
            f"fresh connection was answered after {outcome.latency_s * 1000:.0f} ms")
    return Stall(case_id, after, writes, time.time() - began, held, _at(transcript, ended))


#: a fresh connection answered this late after a case's silence was held by the stall too (seconds; at least ten
#: times the box's usual latency, at most half of time_out)
HELD_S = 0.5


def held(transcript: Transcript, fresh: Outcome, usual_s: float, time_out_s: float, case_id: str, last_sent: bytes,
         writes: int, ended: float) -> Stall | None:
    """The case went silent past time_out and the fresh connection asked right after it (``ended``: time.time()
    then) was answered, but late: the whole box was still silent then (a stall that ended during that wait). None:
    answered promptly."""
    if not transcript.timeouts or not isinstance(fresh, (Answer, Malformed)):
        return None
    if fresh.latency_s < min(max(HELD_S, 10 * usual_s), time_out_s / 2):
        return None
    after, began = _after(transcript, last_sent, ended), _began(transcript, ended)
    who = (f"the case's connection went unanswered for time_out, and a fresh connection asked right after was "
           f"answered only after {fresh.latency_s * 1000:.0f} ms")
    return Stall(case_id, after, writes, time.time() - began, who, _at(transcript, ended))


def verdict(stall: Stall, last_sent: bytes) -> CaseVerdict:
    return CaseVerdict(Verdict.FAIL, f"T1/S4: {stall.describe()} (a box-wide event, not a verdict on this case's "
                                     "input)", requirement=STALL_TEXT, expected="every connection answered within "
                       "time_out", observed=stall.describe(), sent=last_sent, judged=("T1", "S4"), signature=STALL)
