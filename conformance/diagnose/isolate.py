"""Isolation, the general experiment: the minimal difference between a failing exchange and the nearest passing one.

For a root cause no family explains, the requests its cases sent are paired with the nearest valid
request (:func:`.differences.nearest_valid`) and the difference is narrowed live, each candidate on a
fresh connection (delta debugging, :func:`.differences.ddmin`): first by field (a header field, a
block's index, one float value, the check field), then byte by byte within a multi-byte field, then
the field's bytes one at a time (which byte the box reads). A root cause whose cases sent several
frames is put to segmentation (one write vs one frame at a time) and to what came before on the
connection (the fewest earlier frames that still show it, :func:`.shrink.shrink`, vs a fresh
connection). The title is built from what was isolated (:mod:`.isolation_titles`).

What isolation could not pin keeps the catalogue's story, ``unconfirmed:``, and its diagnosis lists
what was tried (this experiment's exchanges and finding).
"""

from __future__ import annotations

from collections.abc import Sequence

from ..model.verdicts import CaseResult, RootCause
from ..protocol.constants import HEADER_LEN
from . import dimensions, segments
from . import isolation_titles as T
from .differences import (
    REQUESTS,
    Isolated,
    Place,
    applied,
    ddmin,
    differing,
    field_bytes,
    float_class,
    low_high,
    nearest_valid,
    place,
    units,
)
from .experiments import Prober
from .families import Found
from .hypotheses import Exchange, Experiment, Mechanism, Status
from .passing import standard, standards
from .probes import cut_short, full_wait
from .reproduce import expect_of, reproduce
from .shrink import split_frames
from .titles import name

#: distinct failing requests isolated per root cause
MAX_REQUESTS = 3
#: no isolation is started with less than this left of the phase (seconds)
MIN_LEFT_S = 1.0
#: the catalogue's stories that only say what the cases saw: confirmed again on a fresh connection, still no mechanism
GENERIC = ("wrong-code", "fuzz", "own", "unanswered", "closes", "unanswered-errors", "unreachable")
_CLAUSES = {"start_word": ("F1",), "version": ("F2", "A5"), "transfer_type": ("F3", "A5"), "action": ("A5",),
            "block_type": ("B5",), "block_count": ("B5",), "block_length": ("B5", "F5"), "error_code": ("A3",),
            "check": ("F6",), "index": ("B3",), "value": ("B4",)}


class Isolator:
    """Isolation for the root causes of one diagnose phase; one mechanism per isolated difference."""

    def __init__(self, p: Prober) -> None:
        self.p = p
        self.mechanisms: dict[tuple[object, ...], Mechanism] = {}
        self._exp = Experiment("isolate", "")
        self.segments = segments.Segments(p)  # R3/R4: the split point or the segment isolated, once per phase

    def diagnose(self, cause: RootCause, cases: Sequence[CaseResult]) -> Found:
        """Isolation for ``cause``; when it pins nothing, the case sent again (:func:`.reproduce.reproduce`),
        whose generic story stays unconfirmed."""
        exp = Experiment("isolate", "the failing request against the nearest valid one, the difference narrowed "
                                    "field by field and byte by byte (ddmin), each candidate on a fresh connection; "
                                    "several frames: one write vs one at a time, and the fewest earlier frames")
        found = Found(exp)
        self._exp = exp
        by_id = {c.id: c for c in cases}
        members = [by_id[i] for i in cause.cases if i in by_id and by_id[i].sent_hex and "…" not in by_id[i].sent_hex]
        notes: list[str] = []
        if any(_udp(m) for m in members):  # datagrams are not put to TCP experiments
            notes.append("UDP cases not isolated over TCP")
            members = [m for m in members if not _udp(m)]
        got = (self._whole_box(exp, cause) or self.segments.isolate(exp, [by_id[i] for i in cause.cases if i in by_id])
               or self._isolate(exp, members, notes))
        exp.finding = got.title if got is not None else "; ".join(notes) or "no case quotes a whole request"
        if got is not None:
            mech = self.mechanisms.get(got.key)
            if mech is None:
                mech = Mechanism(f"isolated-{got.key[0]}", frozenset({got.action or 0}), exp.name, got.title,
                                 got.clauses, tuple((f, expect_of(f, self.p)) for f in got.repro),
                                 dict(got.detail))
                self.mechanisms[got.key] = mech
            found.mechanisms.append(mech)
            found.stories["isolated"] = (Status.CONFIRMED, got.title)
            return found
        found.stories["isolated"] = (Status.RULED_OUT if members else Status.UNTESTED, exp.finding)
        member = next((m for m in members if m.signature is not None), None)
        if member is None or self.p.left() < MIN_LEFT_S:
            return found
        again = reproduce(self.p, member, cause.title)
        found.stories.update(again.stories)
        exp.exchanges += again.experiment.exchanges
        exp.finding += f"; sent again: {again.experiment.finding}"
        if again.mechanisms and not (cause.kind in GENERIC and again.mechanisms[0].kind in ("reproduces", "order-dependent")):
            found.mechanisms += again.mechanisms
        elif again.mechanisms:  # seen again, but no mechanism isolated: the story stays unconfirmed
            found.stories[again.mechanisms[0].kind] = (Status.CONSISTENT, "seen again on a fresh connection; isolation "
                                                                          "found no difference that explains it")
        return found

    def _whole_box(self, exp: Experiment, cause: RootCause) -> Isolated | None:
        """What every answer shows (the check field of TCP answers), and what grows with the requests on a
        connection (the latency): dimensions of the box, not of one request."""
        if "F6" in cause.clauses and self.p.left() > MIN_LEFT_S:
            return dimensions.answer_check(self.p, exp)
        if "T2" in cause.clauses and self.p.left() > MIN_LEFT_S:
            return dimensions.latency_growth(self.p, exp)
        return None

    # -- requests ----------------------------------------------------------------------------------------
    def _isolate(self, exp: Experiment, members: list[CaseResult], notes: list[str]) -> Isolated | None:
        """The members nearest to a passing request first (the fewest differing fields; several frames last)."""
        done: set[tuple[object, ...]] = set()
        for case in sorted(members, key=lambda c: _distance(self.p, c)):
            if len(done) >= MAX_REQUESTS or self.p.left() < MIN_LEFT_S:
                notes.append("out of time")
                break
            try:
                frames = split_frames(bytes.fromhex(case.sent_hex), self.p.codec)
            except ValueError:
                continue
            if len(frames) > 1:
                got = self._sequence(exp, case, frames, notes)
                if got is not None:
                    return got
                continue
            if expect_of(frames[0], self.p).kind == "valid":
                key = ("valid", frames[0][5])
                if key not in done:
                    done.add(key)
                    got = self._valid(exp, frames[0], notes, case)
                    if got is not None:
                        return got
                continue
            passing = nearest_valid(frames[0], self.p.codec)
            diff = differing(frames[0], passing) if passing is not None else []
            if passing is None or not diff:
                notes.append(f"{case.id}: no valid request of the same length differs from it")
                continue
            fields = tuple(sorted({place(o, len(passing), REQUESTS[passing[5]][0]).field for o in diff}))
            if fields in done:
                continue
            done.add(fields)
            got = self._request(exp, frames[0], passing, notes, members)
            if got is not None:
                return got
        return None

    def _fails(self, exp: Experiment, frame: bytes) -> bool | None:
        """Whether the box's answer to ``frame`` alone, on a fresh connection, is outside its legal set."""
        expect = expect_of(frame, self.p)
        if not full_wait(self.p):  # a silence cut short by the deadline would read as a failure
            return None
        ex = self.p.exchange([frame], quiet=[expect.kind == "invalid"], settle=False)
        if ex is None or not ex.reached:
            return None
        exp.exchanges.append(ex)
        return bool(expect.broken_by(ex.reading(0)))

    def _valid(self, exp: Experiment, frame: bytes, notes: list[str], case: CaseResult) -> Isolated | None:
        """A valid request the box mishandled: vs the same request with the values every probe sends (which
        value); alone and whole vs split (R3); unanswered while a NONE behind it is answered."""
        first = self._fails(exp, frame)
        if first is None:
            return None
        if not first:
            got = dimensions.split(self.p, exp, frame)
            if got is None:
                notes.append(f"{case.id}: answered right alone on a fresh connection, whole and split")
            return got
        for passing in standards(self.p, frame):  # the first the box answers right is the passing request
            if differing(frame, passing) and self._fails(exp, passing) is False:
                return self._request(exp, frame, passing, notes, [case], checked=True)
        got = dimensions.unanswered(self.p, exp, frame)
        if got is None:
            notes.append(f"{case.id}: the request alone fails, with the values every probe sends")
        return got

    def _request(self, exp: Experiment, failing: bytes, passing: bytes, notes: list[str],
                 members: list[CaseResult], checked: bool = False) -> Isolated | None:
        first = True if checked else self._fails(exp, failing)
        if not first:
            notes.append(f"{failing.hex()}: " + ("out of time" if first is None else "answered right alone on a fresh "
                                                 "connection"))
            return None
        if self._fails(exp, passing) is not False:
            notes.append(f"the nearest valid request {passing.hex()} fails too")
            return None
        size = REQUESTS[passing[5]][0]
        groups = units(differing(failing, passing), len(passing), size)

        def fails_with(offsets: list[int]) -> bool | None:
            return self._fails(exp, applied(passing, failing, offsets))

        chosen = ddmin(groups, lambda gs: fails_with([o for g in gs for o in g]),
                       max_tests=8 + 4 * max(1, len(groups)).bit_length())
        if len(chosen) > 1 and len({place(g[0], len(passing), size).field for g in chosen}) > 1:
            notes.append(f"{failing.hex()}: {len(chosen)} differences still needed after narrowing")
        offsets = [o for g in chosen for o in g]
        where = place(offsets[0], len(passing), size)
        if where.field == "value" and len(chosen) > 1:
            offsets = chosen[0]
            if not fails_with(offsets):  # one value alone does not show it: name nothing
                notes.append(f"{failing.hex()}: no one value alone shows it")
                return None
        if len(offsets) > 1 and where.field in ("version", "block_length", "start_word", "error_code"):
            offsets = ddmin(offsets, fails_with, 4)
        return self._name(exp, failing, passing, where, offsets, members)

    def _name(self, exp: Experiment, failing: bytes, passing: bytes, where: Place, offsets: list[int],
              members: list[CaseResult]) -> Isolated:
        action = passing[5] if failing[5] in REQUESTS or where.field == "action" else failing[5]
        repro = (applied(passing, failing, offsets),)
        order = self.p.profile.byte_order
        clauses = _CLAUSES.get(where.field, ("R1",))
        if expect_of(failing, self.p).kind == "invalid":  # a parse error answered 0000 breaks R1 (and A3) too
            clauses = tuple(dict.fromkeys((*clauses, "R1", *(("A3",) if REQUESTS.get(action or 0, (0,))[0] else ()))))
        if where.field == "index":
            at = HEADER_LEN + (where.block - 1) * REQUESTS[passing[5]][0]
            title = T.index_unchecked(where.block, failing[at], passing[at], self.p.profile.first_index, action)
            return Isolated(("index",), title, clauses, action, repro, {"block": where.block, "value": failing[at]})
        if where.field == "value":
            return self._value(exp, failing, passing, where, action, repro)
        if where.field == "check":
            title = T.differs("check", failing[-2:].hex(" "), action, _what(exp))
            return Isolated(("check",), title, clauses, action, repro, {})
        value = field_bytes(failing, where.field).hex(" ")
        values = [value] + [v for v in _values(members, where.field, self.p) if v != value]
        how = self._bytes(exp, passing, failing, where.field, order)
        if expect_of(failing, self.p).kind != "invalid":
            return Isolated(("differs", where.field), T.differs(where.field, value, action, _what(exp)), clauses,
                            action, repro, {"field": where.field, "value": value})
        if how in ("low", "high"):
            title = T.one_byte(where.field, how == "low", value, action)
        elif how == "from-type":
            title = T.length_from_type(value, action, REQUESTS.get(action or 0, (25, 1))[0] or 25)
        else:
            title = T.unchecked(where.field, values[:3], action)
        return Isolated((how, where.field), title, clauses, action, repro, {"field": where.field, "values": values[:6],
                                                                              "bytes": how})

    def _value(self, exp: Experiment, failing: bytes, passing: bytes, where: Place, action: int | None,
               repro: tuple[bytes, ...]) -> Isolated:
        """A float value isolated: the byte order the box reads, a bound between the passing and failing values,
        or the value's class."""
        at = HEADER_LEN + (where.block - 1) * REQUESTS[passing[5]][0] + 1 + 4 * where.part
        order = self.p.profile.float_byte_order
        raw = failing[at:at + 4]
        kind = float_class(raw, order) or f"{dimensions.as_float(raw, order):g}"
        invalid = expect_of(failing, self.p).kind == "invalid"
        what = _what(exp)
        found = dimensions.float_value(self.p, passing, failing, at, lambda f: self._accepts(exp, f))
        if found is not None and found[0] == "byte-order":
            return Isolated(("float-order", found[1]), T.float_order(found[1], kind, action, invalid), ("B4", "F4"),
                            action, repro, {"order": found[1]})
        if found is not None and found[0] == "threshold":
            above = dimensions.as_float(raw, order) > dimensions.as_float(passing[at:at + 4], order)
            part = T.part_name(action, where.part)
            return Isolated(("value-bound", action, part, found[1]), T.value_bound(action, part, found[1], above, what),
                            ("B1", "B2", "B4"), action, repro, {"bound": found[1], "above": above})
        if invalid:
            return Isolated(("value-accepted", kind), T.value_accepted(kind, action, where.block, where.part),
                            ("B4",), action, repro, {"class": kind})
        return Isolated(("value-refused", kind, action), T.value_refused(kind, action, where.block, where.part, what),
                        ("B1", "B4"), action, repro, {"class": kind})

    def _accepts(self, exp: Experiment, frame: bytes) -> bool | None:
        """Whether the box answers ``frame`` 0000 with its action (alone, on a fresh connection)."""
        if not full_wait(self.p):
            return None
        ex = self.p.exchange([frame], quiet=[expect_of(frame, self.p).kind == "invalid"], settle=False)
        if ex is None or not ex.reached:
            return None
        exp.exchanges.append(ex)
        return any(a.action == frame[5] and a.error == 0 for a in ex.reading(0).answers)

    def _bytes(self, exp: Experiment, passing: bytes, failing: bytes, name: str, order: str) -> str:
        """Which bytes of a 16-bit field the box reads: "low" (only the low byte), "high", "from-type" (the block
        length ignored for the block type's), or "unchecked"."""
        lh = low_high(name, order)
        if lh is None:
            return "unchecked"
        accepted = []
        for at in lh:
            probe = bytearray(passing)
            probe[at] = failing[at] if failing[at] != passing[at] else passing[at] ^ 0x01
            accepted.append(self._fails(exp, bytes(probe)))
        low_only, high_only = accepted[0] is True, accepted[1] is True  # the probe changing that byte is answered 0000
        if high_only and not low_only:
            return "low"  # a changed high byte goes unnoticed: only the low byte is read
        if low_only and not high_only:
            return "high"
        if name == "block_length" and low_only and high_only:
            pose = bytearray(self.p.valid_request(0x23))
            low, _ = lh
            pose[low] = 0x05
            return "from-type" if self._fails(exp, bytes(pose)) else "unchecked"
        return "unchecked"

    # -- several frames ---------------------------------------------------------------------------------------
    def _sequence(self, exp: Experiment, case: CaseResult, frames: list[bytes], notes: list[str]) -> Isolated | None:
        """Several frames: the first one mishandled when each is sent after the last was answered; the fewest
        earlier frames that still spoil it (ddmin; none: a defect of that request alone, isolated as one); not
        mishandled one at a time but in one write: segmentation (R4)."""

        def broken_at(candidate: Sequence[bytes], together: bool = False) -> tuple[int | None, Exchange | None]:
            if not full_wait(self.p):
                return None, None
            ex = self.p.exchange(list(candidate), quiet=[True] * (len(candidate) - 1) + [False], settle=False,
                                 together=together)
            if ex is None or not ex.reached or cut_short(self.p):
                return None, None
            exp.exchanges.append(ex)
            if together:
                heard = sum(len(r.answers) for r in ex.readings)
                return (len(candidate) - 1 if heard < sum(expect_of(f, self.p).kind == "valid" for f in candidate)
                        else -1), ex
            bad = next((k for k, f in enumerate(candidate) if expect_of(f, self.p).broken_by(ex.reading(k))), -1)
            return bad, ex

        at, ex = broken_at(frames)
        if at is None or ex is None:
            return None
        if at < 0:
            bad, ex = broken_at(frames, together=True)
            if bad is None or bad < 0 or ex is None:
                notes.append(f"{case.id}: not seen again, one frame at a time nor in one write")
                return None
            heard = sum(len(r.answers) for r in ex.readings)
            return Isolated(("coalesced",), T.coalesced(min(heard, len(frames)), len(frames)), ("R4", "A1"),
                            frames[-1][5] if len(frames[-1]) > 5 else None, tuple(frames),
                            {"frames": len(frames), "one_write": True})
        last, earlier = frames[at], frames[:at]

        def spoils(prefix: list[bytes]) -> bool | None:
            k, _ = broken_at([*prefix, last])
            return None if k is None else k == len(prefix)

        alone = spoils([])
        if alone is None:
            return None
        if alone or not earlier:
            passing = nearest_valid(last, self.p.codec)
            if passing is not None and differing(last, passing):
                return self._request(exp, last, passing, notes, [case])
            notes.append(f"{case.id}: frame {at + 1} alone shows it, and no valid request of its length differs")
            return None
        kept = ddmin(earlier, spoils, max_tests=12)
        _, ex = broken_at([*kept, last])  # what the box does there, shown once more
        return self._after(ex, kept, last)

    def _after(self, ex: Exchange | None, prior: list[bytes], last: bytes) -> Isolated:
        """``last`` mishandled after the ``prior`` frames on the same connection, answered right alone (after a
        CycleOn: on that connection only, or on every connection?)."""
        if any(len(f) > 5 and f[5] == 0x01 for f in prior) and len(last) > 5 and last[5] in (0x23, 0x24, 0x25):
            held = dimensions.connection_held(self.p, self._exp, last)
            if held is not None:
                return held
        described = _describe(prior)
        action = last[5] if len(last) > 5 else None
        frames = (*prior, last)
        closed = ex is not None and any(ex.reading(k).closed for k in range(len(ex.frames) - 1))
        reading = ex.reading(len(ex.frames) - 1) if ex is not None else None
        if closed or (reading is not None and reading.closed and not reading.answers):
            return Isolated(("closes-after", described), T.closes_after(described), ("A1", "S1"), action, frames,
                            {"prior": described})
        what = T.done_to(reading.answers[0].error or 0 if reading is not None and reading.answers else None,
                         reading is not None and reading.closed)
        garbage = any(expect_of(f, self.p).kind == "invalid" for f in prior)  # after bytes that are no request: R6
        return Isolated(("after-prior", described, what), T.after_prior(described, what, action),
                        ("R6", "A1") if garbage else ("A1",), action,
                        frames, {"prior": described})


def _what(exp: Experiment) -> str:
    """What the box did to the first failing request isolated (its first exchange)."""
    for ex in exp.exchanges:
        for r in ex.readings:
            if r.answers:
                a = r.answers[0]
                return T.did(a.action, a.error or 0, False)
            if r.closed:
                return T.did(None, None, True)
    return T.did(None, None, False)


def _values(members: list[CaseResult], name: str, p: Prober) -> list[str]:
    """The values of header field ``name`` in the single-frame requests of ``members`` that differ from the
    nearest valid request there (what else the catalogue saw answered the same way)."""
    out: list[str] = []
    for case in members:
        try:
            frames = split_frames(bytes.fromhex(case.sent_hex), p.codec)
        except ValueError:
            continue
        passing = nearest_valid(frames[0], p.codec) if len(frames) == 1 else None
        if passing is not None and field_bytes(frames[0], name) != field_bytes(passing, name):
            value = field_bytes(frames[0], name).hex(" ")
            if value not in out:
                out.append(value)
    return out


def _describe(frames: Sequence[bytes]) -> str:
    """Earlier frames as a title names them: their actions when each is a request, else their first bytes."""
    names = [name(f[5]) if len(f) >= HEADER_LEN and f[:2] == b"\xfe\xfe" else f[:12].hex(" ") for f in frames]
    return ", ".join(names[-3:]) if len(names) <= 3 else f"{len(names)} frames ending {', '.join(names[-2:])}"


def _distance(p: Prober, case: CaseResult) -> int:
    """How far a case's request is from the nearest passing one: its differing fields (several frames: far)."""
    try:
        frames = split_frames(bytes.fromhex(case.sent_hex), p.codec)
    except ValueError:
        return 10_000
    if len(frames) != 1:
        return 1_000 + len(frames)
    frame = frames[0]
    passing = standard(p, frame) if expect_of(frame, p).kind == "valid" else nearest_valid(frame, p.codec)
    if passing is None or len(passing) != len(frame):
        return 500
    return len(units(differing(frame, passing), len(frame), REQUESTS.get(passing[5], (0, 0))[0]))


def _udp(case: CaseResult) -> bool:
    return bool({"F7", "R7"} & set(case.clauses))
