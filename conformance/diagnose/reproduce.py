"""Request-dependent vs connection- or order-dependent: what a case saw, sent again on a fresh connection.

The bytes a root cause's first case sent (when its verdict quotes them whole) are cut into
frames and sent on a fresh connection. If the box does what the case saw (the same answer —
action and error —, a malformed answer, silence, a close), the frames are shrunk to the fewest
that still show it (:mod:`.shrink`): one frame left is a defect of that request alone
(``reproduces``); more is a defect that needs the frames before it (``order-dependent``). Not
seen again at all: the defect depended on the connection, the cycle or the order of the cases.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..model.signature import Sig, Signature
from ..model.verdicts import CaseResult
from ..protocol import ProtocolError, TransferType, Transport, parse_header
from ..protocol.constants import HEADER_LEN
from .experiments import Prober
from .families import Found
from .hypotheses import LEGAL_CODES, Exchange, Expect, Experiment, Mechanism, Status
from .shrink import shrink, split_frames


def shows(sig: Signature, ex: Exchange) -> bool:
    """Whether the exchange shows what the case's verdict saw."""
    readings = ex.readings
    if sig.kind is Sig.CLOSED:
        return any(r.closed for r in readings)
    if sig.kind in (Sig.SILENCE, Sig.SKIPPED) and ex.together:
        return sum(len(r.answers) for r in readings) < len(ex.frames)  # some frame went unanswered
    if sig.kind in (Sig.SILENCE, Sig.SKIPPED):
        return len(readings) == len(ex.frames) and readings[-1].silent if sig.kind is Sig.SILENCE else \
            any(r.silent for r in readings)
    if sig.kind is Sig.ANSWER:
        return any(a.malformed for r in readings for a in r.answers)
    if sig.reply is not None:
        want = (sig.reply.action, sig.reply.error)
        return any((a.action, a.error) == want for r in readings for a in r.answers)
    return False


def expect_of(frame: bytes, prober: Prober) -> Expect:
    """A frame's legal answers: a valid request's (exactly one, echoed, a legal code) or a parse error's (no 0000)."""
    action = 0
    if len(frame) >= HEADER_LEN:
        header = parse_header(frame[:HEADER_LEN])
        action = header.action  # what a box reading the header takes for the action, whatever its start word (F1)
    try:
        parsed = prober.codec.parse(frame, Transport.TCP, TransferType.ROBOT_TO_BOX)
    except ProtocolError:
        return Expect("invalid", action)
    except ValueError:
        return Expect("invalid", action)
    return Expect("valid", int(parsed.action), LEGAL_CODES.get(int(parsed.action), (0,)))


def reproduce(p: Prober, case: CaseResult, title: str) -> Found:
    found = Found(Experiment(f"reproduce {case.id}", f"the bytes case {case.id} sent, on a fresh connection; "
                                                     "then as few of its frames as still show the defect"))
    sig = case.signature
    if sig is None or not case.sent_hex or "…" in case.sent_hex:
        found.stories["reproduces"] = (Status.UNTESTED, "the case's bytes are not quoted whole")
        return found
    try:
        frames = split_frames(bytes.fromhex(case.sent_hex), p.codec)
    except ValueError:
        found.stories["reproduces"] = (Status.UNTESTED, "the case's bytes are not readable")
        return found

    together = False

    def seen(candidate: Sequence[bytes]) -> bool | None:
        ex = p.exchange(list(candidate), quiet=[True] * (len(candidate) - 1) + [False], settle=False,
                        together=together)
        if ex is None or not ex.reached:
            return None
        found.experiment.exchanges.append(ex)
        return shows(sig, ex)

    first = seen(frames)
    if first is False and len(frames) > 1:  # as the case sent them: in one write (R4: several frames, one segment)
        together = True
        first = seen(frames)
    if not first:
        status = Status.UNTESTED if first is None else Status.RULED_OUT
        found.stories["reproduces"] = (status, "out of time" if first is None else
                                       "not seen again on a fresh connection: it depended on the connection, the "
                                       "cycle or the order of the cases")
        found.experiment.finding = found.stories["reproduces"][1]
        return found
    kept = shrink(frames, seen)
    kind = "reproduces" if len(kept) == 1 else "order-dependent"
    repro = tuple((f, expect_of(f, p)) for f in kept)
    final = title if kind == "reproduces" else f"{title} — only after {len(kept) - 1} earlier frame(s) on the same connection"
    actions = {e.action for _, e in repro}
    found.mechanisms.append(Mechanism(kind, frozenset(actions), found.experiment.name, final,
                                      tuple(dict.fromkeys(case.judged or case.clauses)), repro,
                                      {"frames": len(kept), "title": final, "one_write": together}))
    found.stories[kind] = (Status.CONFIRMED, f"{len(kept)} of {len(frames)} frames show it on a fresh connection")
    found.experiment.finding = found.stories[kind][1]
    return found
