"""Which legal framing explains what a box did with some bytes (sans-I/O).

:func:`explain` searches the framings of :mod:`.framings` for the one that explains
the box's answers (in order) and how the exchange ended with the fewest broken
requirements: MUST first, then SHOULD, then the fewest departures from the reference
framing (which keeps the messages familiar). Its findings are what *no* legal framing
explains, so a verdict never depends on which legal framing a box chose.

The search is a shortest path over (offset, answers used, garbage seen); offsets only
grow. A run of junk (bytes that are not a request and whose length no receiver trusts)
is taken in one step: walking it costs nothing, and each junk event may take one
non-zero answer (A5 allows an error answer to bytes that are not a request).
:func:`explain_events` judges events known in advance (UDP datagrams, a session's
requests) the same way, with no framing choices.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from .answers import Cycle, Expectation, Finding, Seen, judge_answer, unanswered
from .framings import BAD, PENDING, VALID, End, Event, Explanation, Reader, Spot
from .levels import Level
from .profile import Profile

#: At most this many departures from the reference framing are named in ``Explanation.framing``.
NOTES = 3

Cost = tuple[int, int, int]  # (MUST findings, SHOULD findings, departures from the reference framing)
_ZERO: Cost = (0, 0, 0)
_State = tuple[int, int, bool]  # (offset, answers used, garbage seen)


@dataclass(frozen=True, slots=True)
class _Step:
    cost: Cost
    findings: tuple[Finding, ...] = ()
    event: Event | None = None
    to: _State | None = None  # None: the exchange ends here
    unasked: int | None = None  # the answer this step leaves unexplained
    note: str = ""  # a departure from the reference framing


def _cost(findings: Sequence[Finding], departures: int = 0) -> Cost:
    must = sum(1 for f in findings if f.level is Level.MUST)
    return (must, len(findings) - must, departures)


def _add(a: Cost, b: Cost) -> Cost:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


class _Chain:
    """A fixed sequence of events (UDP datagrams, or expectations known in advance): no framing choices."""

    def __init__(self, expects: Sequence[Expectation], independent: bool) -> None:
        self.expects = list(expects)
        self.n = len(self.expects)
        #: each event stands alone (UDP datagrams): bad bytes before a request excuse nothing (no R6)
        self.independent = independent

    def spot(self, p: int) -> Spot:
        exp = self.expects[p]
        return Spot(VALID if exp.valid else BAD, exp, end=p + 1)

    def targets(self, p: int) -> list[int]:
        return [p + 1]

    def junk_run(self, p: int) -> tuple[int, int] | None:
        return None

    def reference(self, p: int) -> int:
        return p + 1


class _Search:
    def __init__(self, graph: Reader | _Chain, answers: Sequence[Seen], end: End, end_text: str,
                 first_bad: str) -> None:
        self.graph = graph
        self.answers = answers
        self.end = end
        self.end_text = end_text
        self.first_bad = first_bad
        self.best: dict[_State, tuple[Cost, _Step]] = {}

    def positions(self) -> list[int]:
        """Every offset some legal framing reaches, from 0."""
        seen, todo, n = {0}, [0], self.graph.n
        while todo:
            p = todo.pop()
            if p >= n:
                continue
            spot = self.graph.spot(p)
            run = self.graph.junk_run(p) if spot.kind == BAD else None
            if run is not None:
                nxt = [run[0]]
            elif spot.kind == VALID:
                nxt = [spot.end]
            elif spot.kind == BAD:
                nxt = self.graph.targets(p)
            else:
                nxt = []
            for q in nxt:
                if q not in seen:
                    seen.add(q)
                    todo.append(q)
        return sorted(seen, reverse=True)

    def run(self) -> Explanation:
        k = len(self.answers)
        for p in self.positions():
            for i in range(k, -1, -1):
                for bad in (True, False):
                    self.best[(p, i, bad)] = self._choose(p, i, bad)
        return self._trace((0, 0, False))

    def _choose(self, p: int, i: int, bad: bool) -> tuple[Cost, _Step]:
        best: tuple[Cost, _Step] | None = None
        for step in self._steps(p, i, bad):
            total = step.cost if step.to is None else _add(step.cost, self.best[step.to][0])
            if best is None or total < best[0]:
                best = (total, step)
        assert best is not None  # "unasked" or a terminal is always possible
        return best

    # -- the steps a box may take at (p, i, bad) ----------------------------------------------------
    def _steps(self, p: int, i: int, bad: bool) -> list[_Step]:
        k, graph, end = len(self.answers), self.graph, self.end
        steps: list[_Step] = []
        if i < k:
            found = self._unasked(i)
            steps.append(_Step(_cost(found), tuple(found), to=(p, i + 1, bad), unasked=i))
        done = i == k
        if p >= graph.n:
            if done:
                steps.append(self._terminal(bad, "the end of the bytes"))
            return steps
        spot = graph.spot(p)
        if done and end is End.CLOSED and spot.kind != BAD:
            steps.append(self._terminal(bad, "a close"))
        if spot.kind == PENDING:
            if done and end is not End.CLOSED:
                steps.append(_Step(_ZERO, note="waits for the rest of a frame"))
            return steps
        exp = spot.exp
        assert exp is not None
        if done and end is End.SILENT:
            if bad or spot.kind == BAD:
                found = [Finding(Level.SHOULD, "R6", "R6: after bytes that are not a frame the box SHOULD resynchronise "
                                 "or close; hanging silently is NON-STRICT", self._how(), "end/hang")]
                if spot.kind == BAD:
                    found += unanswered(exp, bad, self._how())
            else:
                found = [Finding(Level.MUST, "T1", "A1/T1: every well-formed request is answered within time_out",
                                 f"{self._how()} ({exp.message} unanswered)", "end/silence")]
            steps.append(_Step(_cost(found), tuple(found)))
        if spot.kind == VALID:
            if i < k and self.answers[i].action == exp.action:
                found = judge_answer(exp, self.answers[i])
                steps.append(_Step(_cost(found), tuple(found), Event(p, spot.end, exp, i), (spot.end, i + 1, bad)))
            found = unanswered(exp, bad, self._how())
            steps.append(_Step(_cost(found), tuple(found), Event(p, spot.end, exp, None), (spot.end, i, bad)))
            return steps
        # bytes that are not a valid request: answered or not, then trusted, resynchronised, waited on
        run = graph.junk_run(p)
        if run is not None:
            return steps + self._trusted_junk(p, i, spot) + self._run_steps(p, i, spot, run)
        choices: list[tuple[int | None, list[Finding]]] = [(None, unanswered(exp, bad, self._how()))]
        if i < k:
            choices.append((i, judge_answer(exp, self.answers[i])))
        reference = graph.reference(p)
        for answer, found in choices:
            j = i + (answer is not None)
            base = _cost(found)
            event = Event(p, spot.end if spot.end >= 0 else p + 1, exp, answer)
            after = not getattr(graph, "independent", False)
            for q in graph.targets(p):
                dep = 0 if q == reference else 1
                note = "" if not dep else f"resumes at offset {q} after rejecting the bytes at offset {p}"
                steps.append(_Step(_add(base, (0, 0, dep)), tuple(found), event, (q, j, after), note=note))
            if spot.waits and j == k and end is not End.CLOSED:
                steps.append(_Step(_add(base, (0, 0, 1)), tuple(found), event, None,
                                   note=f"trusts the header at offset {p} and waits for its body"))
            if j == k and end is End.CLOSED:
                steps.append(_Step(base, tuple(found), event, None, note=f"closes after the bytes at offset {p}"))
        return steps

    def _trusted_junk(self, p: int, i: int, spot: Spot) -> list[_Step]:
        """A header only R6 (a) trusts (it announces more than the largest legal frame): refused or not, the box
        may skip its announced length and so wait for it, which explains a silence after it."""
        k, exp = len(self.answers), spot.exp
        if not spot.waits or self.end is End.CLOSED or exp is None or i < k - 1:
            return []
        found = unanswered(exp, False, self._how()) if i == k else judge_answer(exp, self.answers[i])
        note = f"trusts the header at offset {p} and waits for the length it announces"
        return [_Step(_add(_cost(found), (0, 0, 1)), tuple(found), Event(p, p + 1, exp, None if i == k else i), None,
                      note=note)]

    def _run_steps(self, p: int, i: int, spot: Spot, run: tuple[int, int]) -> list[_Step]:
        """A run of junk from ``p`` to ``run[0]`` with ``run[1]`` junk events: each may take one answer."""
        exit_at, count = run
        exp = spot.exp
        assert exp is not None
        k, steps = len(self.answers), []
        found: list[Finding] = []
        for used in range(0, min(count, k - i) + 1):
            if used:
                found = found + judge_answer(exp, self.answers[i + used - 1])
            event = Event(p, exit_at, exp, i if used else None)
            steps.append(_Step(_cost(found), tuple(found), event, (exit_at, i + used, True)))
            if i + used == k and self.end is End.CLOSED:
                steps.append(_Step(_cost(found), tuple(found), event, None, note=f"closes after the bytes at offset {p}"))
        return steps

    def _terminal(self, allowed: bool, where: str) -> _Step:
        if self.end is not End.CLOSED or allowed:
            return _Step(_ZERO)
        found = [Finding(Level.MUST, "A1", "A1: the box answers well-formed requests (it may close only after bytes that "
                                       "are not a request, A5/R6)", f"{self._how()} at {where}", "end/closed")]
        return _Step(_cost(found), tuple(found))

    def _unasked(self, i: int) -> list[Finding]:
        seen = self.answers[i]
        what = f"{seen.text or 'an answer'} (an answer no request of these bytes asked for)"
        if seen.action is None:
            clause = seen.problem or "F1"
            return [Finding(Level.MUST, clause, f"{clause}: the box sends only frames", what, f"answer/{clause}")]
        found: list[Finding] = []
        if seen.problem:
            found.append(Finding(Level.MUST, seen.problem, f"{seen.problem}: the box's answers are conforming frames",
                                 what, f"answer/{seen.problem}"))
        if seen.error == 0 and self.first_bad:
            found.append(Finding(Level.MUST, self.first_bad, "R1: the box never answers 0000 to bytes that break F, B or A5",
                                 what, f"{self.first_bad}/unasked/0000"))
        else:
            found.append(Finding(Level.MUST, "A1", "A1: exactly one answer per request", what, "A1/unasked"))
        return found

    def _how(self) -> str:
        return {End.ANSWERED: "went on to answer the probe", End.CLOSED: "closed the connection",
                End.SILENT: "stayed silent"}[self.end] if not self.end_text else self.end_text

    def _trace(self, state: _State) -> Explanation:
        out = Explanation()
        notes: list[str] = []
        cur: _State | None = state
        while cur is not None:
            _, step = self.best[cur]
            out.findings.extend(step.findings)
            if step.event is not None:
                out.events.append(step.event)
            if step.unasked is not None:
                out.unasked.append(step.unasked)
            if step.note:
                notes.append(step.note)
            cur = step.to
        shown = "; ".join(notes[:NOTES]) + (f"; and {len(notes) - NOTES} more" if len(notes) > NOTES else "")
        out.framing = shown or "reference"
        return out


def explain(
    data: bytes,
    answers: Sequence[Seen],
    end: End,
    profile: Profile,
    *,
    extension: bool = True,
    cycle: Cycle = Cycle.UNKNOWN,
    eof: bool = False,
    end_text: str = "",
    probe_at: int | None = None,
) -> Explanation:
    """The legal framing of ``data`` (sent on one TCP connection) that best explains the
    box's ``answers`` (in order) and how the exchange ended; its findings are what no
    legal framing explains. ``eof``: the robot ended the stream after ``data``.
    ``probe_at``: the offset of the probe request behind the bytes judged (named so)."""
    reader = Reader(bytes(data), profile, extension, cycle, eof, probe_at)
    first_bad = _first_bad(reader)
    return _Search(reader, answers, end, end_text, first_bad).run()


def explain_events(expects: Sequence[Expectation], answers: Sequence[Seen], end: End, end_text: str = "",
                   independent: bool = False) -> Explanation:
    """The same judgement for events known in advance (UDP datagrams, a session's requests):
    no framing choices, only which answer belongs to which event. ``independent``: each
    event stands alone (datagrams), so bad bytes before a request do not make missing its
    answer a mere SHOULD (R6)."""
    first_bad = next((e.clause for e in expects if not e.valid and e.clause), "")
    return _Search(_Chain(expects, independent), answers, end, end_text, first_bad).run()


def _first_bad(reader: Reader) -> str:
    """The first clause the reference framing finds broken (for messages about stray 0000 answers)."""
    p = 0
    while p < reader.n:
        spot = reader.spot(p)
        if spot.kind == PENDING:
            return ""
        if spot.kind == BAD and spot.exp is not None:
            return spot.exp.clause or "R1"
        p = spot.end if spot.end > p else reader.next_start(p + 2)
    return ""

