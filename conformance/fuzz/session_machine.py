"""The session state machine: a hypothesis ``RuleBasedStateMachine`` playing a robot on a command and a stream connection.

Rules: NONE, CycleOn, CycleOff, poses on the stream connection (one at a time or
pipelined, S6), register poses and tolerances on the command connection, ProgIdx and
the result request (only when the box implements extension E), malformed frames from
the frame strategies on either connection (each followed by a probe), and reconnects
of either connection. The machine keeps the box's cycle state (S2, S3: each answer's effect is
:func:`~conformance.protocol.session_table.cycle_after`'s) and the last
answer on each connection; what a request may be answered comes from
:func:`~conformance.protocol.answers.allowed_codes` for that state, and every answer is
judged by the frame oracle (:mod:`.oracle`). Teardown checks liveness on a fresh
connection (R2).

Every answered request marks a transition of :class:`~.state_coverage.StateCoverage`;
:meth:`IsightSession.steer` walks straight to one transition (set the cycle, send the
last request, send the request), which is how the runner (:mod:`.session_runner`) reaches the
transitions random sessions have not.

:func:`machine_for` makes the class for one campaign: the rules are defined once here,
the campaign's context (:class:`SessionContext`) and its malformed-frame strategy are
attached to a subclass.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, precondition, rule

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence, TcpConnection
from ..harness.target import Target, Unreachable
from ..harness.transcript import Transcript
from ..model.verdicts import Verdict
from ..protocol import BLOCK_LEN, REQUEST_SHAPE, Action, BlockType, Header, codec_for
from ..protocol.answers import SENDABLE_RESULTS, allowed_codes
from ..protocol.session_table import Cycle, cycle_after
from .config import CampaignConfig
from .death_first import died, known_death
from .executor import Executor, alive
from .oracle import Expectation, Finding, Rule, judge
from .state_coverage import OPEN, StateCoverage, Transition
from .strategies import FuzzCase, Strategies, _finite

#: Frame categories the machine interleaves as malformed input (stream-safe: no truncation at EOF, no UDP).
MALFORMED = ("F1-start-word", "F2-version", "F3-direction", "A5-unknown-action", "B5-shape", "B3-index",
             "B4-floats", "F5-trailing", "F5-spliced", "F6-check", "R5-oversized", "mutation", "F1-garbage")


@dataclass
class SessionContext:
    """What every session of one campaign shares: the configuration, the budget and the coverage."""

    cfg: CampaignConfig
    strategies: Strategies
    budget: Callable[[], bool]  # may another step run?
    coverage: StateCoverage
    known: set[str] = field(default_factory=set)  # finding keys already reported: a run meeting one again stops
    runs: int = 0
    steps: int = 0
    shrinking: bool = False  # hypothesis is shrinking a failure: every step runs

    def __post_init__(self) -> None:
        profile = self.cfg.profile
        self.codec = codec_for(profile)
        self.first = profile.first_index
        self.order = ">" if profile.float_byte_order == "big" else "<"
        self.stream_target: Target = self.cfg.stream_target or self.cfg.target

    def left(self) -> bool:
        return self.shrinking or self.budget()


class StatefulFailure(AssertionError):
    def __init__(self, finding: Finding, machine: IsightSession, case: FuzzCase) -> None:
        super().__init__(finding.describe())
        self.finding = finding
        self.steps = list(machine.log)
        self.sequence = list(machine.sequence)
        self.transcript: Transcript = machine.tr
        self.case = case


class StatefulHang(BaseException):
    """A session failure hypothesis must not shrink, reported as found: the box stayed silent for time_out
    (every shrink step would wait time_out again), or it died (every step would need a restart: ``dead``).
    A BaseException, so hypothesis lets it through."""

    def __init__(self, failure: StatefulFailure, dead: bool = False) -> None:
        super().__init__(str(failure))
        self.failure = failure
        self.dead = dead


class KnownFailure(BaseException):
    """A session met a failure already reported: the run stops (not shrunk again, not reported twice)."""


def _codes(codes: frozenset[int] | None) -> Any:
    return "answered" if codes is None else {"errors": [f"{c:04X}" for c in sorted(codes)]}


class IsightSession(RuleBasedStateMachine):
    """One robot session against the box (see the module docstring)."""

    ctx: ClassVar[SessionContext]

    def __init__(self) -> None:
        super().__init__()
        ctx = self.ctx
        cfg = ctx.cfg
        self.tr = cfg.transcript if cfg.transcript is not None else Transcript(case_id="FUZZ-stateful")
        self.log: list[str] = []
        self.sequence: list[dict[str, Any]] = []
        self.conns: dict[str, TcpConnection] = {}
        self.last: dict[str, str | None] = {}
        self.executor = Executor(cfg.target, cfg.profile, self.tr, extension=cfg.extension, settle_s=cfg.settle_s)
        self.cycle = Cycle.UNKNOWN
        ctx.runs += 1
        for name in ("command", "stream"):
            self._open(name)
        # a known state to start from: whatever CycleOff gets, the cycle is then off (or unknown)
        self.send("command", Action.CYCLE_OFF, note="start from a known state: CycleOff")

    # -- plumbing ------------------------------------------------------------------------------
    def _open(self, name: str) -> None:
        ctx = self.ctx
        try:
            conn = self.executor.dialer.dial(name, ctx.stream_target if name == "stream" else ctx.cfg.target)
        except Unreachable as exc:
            self._fail(Finding(Verdict.FAIL, "R2", "R2/S4: the box accepts the robot's connections", str(exc),
                               "R2/connect"), FuzzCase("connect", "R2", b"", f"open {name}"))
        self.conns[name] = conn
        self.last[name] = OPEN
        self.sequence.append({"open": name, "target": "stream" if name == "stream" else "command"})
        self.log.append(f"open {name}")

    def _fail(self, finding: Finding, case: FuzzCase, hang: bool = False) -> None:
        """Death first: before a failure is reported the box's liveness is checked; a dead box is R2."""
        ctx = self.ctx
        if not ctx.shrinking:
            live = self.executor.check_alive()
            if not alive(live):
                death = died(finding, live)
                if known_death(death, ctx.known):
                    raise KnownFailure(death.describe())
                raise StatefulHang(StatefulFailure(death, self, case), dead=True)
        if finding.key and finding.key in ctx.known and not ctx.shrinking:
            raise KnownFailure(finding.describe())
        if hang and not ctx.shrinking:
            raise StatefulHang(StatefulFailure(finding, self, case))
        ctx.shrinking = True  # from now on every step runs: hypothesis is shrinking
        raise StatefulFailure(finding, self, case)

    def _body(self, action: Action, raw: bytes) -> tuple[bytes, int, str, frozenset[int] | None]:
        """(blocks, count, what, the answer values E2/E3 allow) of a well-formed ``action`` request from ``raw``."""
        ctx = self.ctx
        shape = REQUEST_SHAPE[action]
        per = BLOCK_LEN[shape.block_type] - 1
        if action is Action.PROG_IDX:
            value = struct.unpack(ctx.order + "i", raw[:4].ljust(4, b"\0"))[0]
            return bytes([ctx.first]) + struct.pack(ctx.order + "i", value), 1, f"ProgIdx {value} (E2)", \
                frozenset({value, 409})
        if action is Action.VISION_RESULT:
            return b"", 0, "result request (E3)", frozenset(SENDABLE_RESULTS)
        if per <= 0:
            return b"", 0, {Action.CYCLE_ON: "CycleOn", Action.CYCLE_OFF: "CycleOff"}.get(action, action.name), None
        raw = _finite(raw[: len(raw) // per * per] or bytes(per), "big" if ctx.order == ">" else "little")
        n = len(raw) // per
        body = b"".join(bytes([(ctx.first + i) & 0xFF]) + raw[i * per : (i + 1) * per] for i in range(n))
        name = {Action.POSE: "pose", Action.REGISTER_POSE: "register pose", Action.TOLERANCE: "tolerance"}[action]
        return body, n, f"{name} ×{n}", None

    def send(self, name: str, action: Action, raw: bytes = b"", note: str = "") -> Outcome:
        """A well-formed ``action`` request on connection ``name``, judged for the cycle state; the state updated."""
        ctx = self.ctx
        body, n, what, values = self._body(action, raw)
        what = note or what
        bt = REQUEST_SHAPE[action].block_type if n else BlockType.EMPTY
        data = ctx.codec.encode_raw(Header(action=action, block_type=bt, block_count=n, block_length=BLOCK_LEN[bt]),
                                    body)
        ok = allowed_codes(action, self.cycle)
        before, last = self.cycle, self.last.get(name)
        outcome = self._exchange(name, data, action, ok, what, values)
        if isinstance(outcome, Answer):
            code = outcome.frame.error_code
            ctx.coverage.record(before, name, last, action, code)
            self.cycle = cycle_after(self.cycle, action, code)
            self.last[name] = action.name if ok is None or code in ok else None
        return outcome

    def _exchange(self, name: str, data: bytes, action: Action, ok: frozenset[int] | None, what: str,
                  values: frozenset[int] | None) -> Outcome:
        ctx = self.ctx
        conn = self.conns[name]
        self.log.append(f"{what} on {name}")
        step: dict[str, Any] = {"raw": data.hex(), "on": name, "expect": _codes(ok), "note": what}
        if values is not None:
            step["expect"] = dict(step["expect"] if isinstance(step["expect"], dict) else {}, values=sorted(values))
        self.sequence.append(step)
        outcome = conn.request(data, what)
        ctx.steps += 1
        exp = Expectation(Rule.ANSWER, "", int(action), what, ok, values=values)
        answers = [outcome] if isinstance(outcome, (Answer, Malformed)) else []
        judgement = judge((exp,), answers, outcome if isinstance(outcome, (Closed, Silence)) else None, ctx.cfg.profile)
        case = FuzzCase("session", "", data, what, expects=(exp,))
        for finding in judgement.failures:
            self._fail(finding, case, hang=isinstance(outcome, Silence))
        if isinstance(outcome, (Closed, Silence)):
            self._open(name)
        return outcome

    def _reopen(self, name: str, why: str) -> None:
        self.conns[name].close(why)
        self.sequence.append({"close": name})
        self.log.append(f"close {name}")
        self._open(name)

    # -- steering --------------------------------------------------------------------------------
    def steer(self, target: Transition, raw: bytes = bytes(24)) -> None:
        """Walk to ``target``: set the cycle on the command connection, make the last answer, send the request."""
        want = Action.CYCLE_ON if target.cycle == Cycle.ON.value else Action.CYCLE_OFF
        name = "CycleOn" if want is Action.CYCLE_ON else "CycleOff"
        self.send("command", want, note=f"{name} (steering to: {target.describe()})")
        if target.last == OPEN:
            self._reopen(target.connection, "steer: a fresh connection")
        else:
            self.send(target.connection, Action[target.last], raw)
        self.send(target.connection, Action[target.action], raw)

    def connection_patterns(self) -> None:
        """The connection patterns at their largest: 16 connections at once, 32 quick reconnects."""
        self._burst(16)
        self._reconnects(32)

    # -- rules -----------------------------------------------------------------------------------
    @rule()
    def none(self) -> None:
        if self.ctx.left():
            self.send("command", Action.NONE)

    @rule()
    def cycle_on(self) -> None:
        if self.ctx.left():
            self.send("command", Action.CYCLE_ON)

    @rule()
    def cycle_off(self) -> None:
        if self.ctx.left():
            self.send("command", Action.CYCLE_OFF)

    @rule(raw=st.binary(min_size=24, max_size=72))
    def pose(self, raw: bytes) -> None:
        if self.ctx.left():
            self.send("stream", Action.POSE, raw)

    @rule(count=st.integers(2, 16), raw=st.binary(min_size=24, max_size=24))
    def pipelined_poses(self, count: int, raw: bytes) -> None:
        """S6/R4: ``count`` poses in one write, then their answers, in order."""
        if self.ctx.left():
            self._pipelined(count, raw)

    def _pipelined(self, count: int, raw: bytes) -> None:
        ctx = self.ctx
        body, _n, _what, _values = self._body(Action.POSE, raw)
        one = ctx.codec.encode_raw(Header(action=Action.POSE, block_type=BlockType.POSE, block_count=1,
                                          block_length=BLOCK_LEN[BlockType.POSE]), body)
        conn = self.conns["stream"]
        what = f"{count} pipelined poses in one write (S6, R4)"
        self.log.append(f"{what} on stream")
        pose = struct.unpack(ctx.order + "6f", body[1:25])
        self.sequence.append({"burst": [{"request": "Pose", "poses": [list(pose)]}] * count, "on": "stream",
                              "note": what})
        start = time.monotonic()
        conn.send(one * count, what)
        exp = Expectation(Rule.ANSWER, "", int(Action.POSE), "a pipelined pose", frozenset({0}))
        case = FuzzCase("session", "", one * count, what, expects=(exp,) * count)
        outcomes: list[Outcome] = []
        end: Outcome | None = None
        while len(outcomes) < count:
            o = conn.next_outcome(since=start)
            if isinstance(o, (Closed, Silence)):
                end = o
                break
            outcomes.append(o)
        ctx.steps += count
        self.last["stream"] = Action.POSE.name
        for finding in judge(case.expects, outcomes, end, ctx.cfg.profile).failures:
            self._fail(finding, case, hang=isinstance(end, Silence))

    @rule(raw=st.binary(min_size=24, max_size=72))
    def register_pose(self, raw: bytes) -> None:
        if self.ctx.left():
            self.send("command", Action.REGISTER_POSE, raw)

    @rule(raw=st.binary(min_size=4, max_size=12))
    def tolerance(self, raw: bytes) -> None:
        if self.ctx.left():
            self.send("command", Action.TOLERANCE, raw)

    @precondition(lambda self: self.ctx.cfg.extension)
    @rule(raw=st.binary(min_size=4, max_size=4))
    def prog_idx(self, raw: bytes) -> None:
        if self.ctx.left():
            self.send("command", Action.PROG_IDX, raw)

    @precondition(lambda self: self.ctx.cfg.extension)
    @rule()
    def vision_result(self) -> None:
        if self.ctx.left():
            self.send("command", Action.VISION_RESULT)

    def malformed(self, case: FuzzCase, on: str) -> None:
        """A malformed frame (and a probe) on either connection: the rule is attached by :func:`machine_for`."""
        if not self.ctx.left():
            return
        self.log.append(f"malformed on {on}: {case.describe()}")
        self.sequence.append({"raw": case.wire.hex(), "on": on, "probe": True, "note": case.describe()[:200]})
        result = self.executor.exchange(self.conns[on], case, f"malformed: {case.describe()}")
        self.ctx.steps += 1
        self.last[on] = None  # the answer to what follows may depend on how the box framed the bytes
        for finding in result.judgement.failures:
            self._fail(finding, case, hang=isinstance(result.end, Silence))
        if any(e.action in (Action.CYCLE_ON, Action.CYCLE_OFF) for e in case.expects):
            self.cycle = Cycle.UNKNOWN
        if result.conn < 0:  # the box closed or hung (allowed after bytes that are not a request)
            self.conns[on].abort("reopened after the box closed or hung")
            self._open(on)

    @rule(count=st.integers(2, 16))
    def many_connections(self, count: int) -> None:
        """R5/S4: ``count`` more connections open at once, a NONE written on each, all closed; then the
        command connection MUST still be answered (the box may refuse or drop the extra ones: it may bound
        its resources)."""
        if self.ctx.left():
            self._burst(count)

    def _burst(self, count: int) -> None:
        ctx = self.ctx
        extras: list[TcpConnection] = []
        for i in range(count):
            try:
                conn = self.executor.dialer.dial(f"extra-{i + 1}", ctx.cfg.target)
            except Unreachable:
                break  # the box bounds its connections: allowed
            extras.append(conn)
            conn.send(ctx.codec.encode_raw(Header(action=Action.NONE)), "NONE on one of many connections (R5)")
        self.log.append(f"{count} more connections at once ({len(extras)} accepted), a NONE on each")
        self.sequence.append({"open": "extra", "target": "command", "count": count})
        for conn in extras:
            conn.close("many connections: done")
        self.sequence.append({"close": "extra"})
        self.send("command", Action.NONE, note=f"NONE on the command connection after {count} more at once (R5)")

    @rule(count=st.integers(2, 32))
    def quick_reconnects(self, count: int) -> None:
        """S5/R2: ``count`` connections opened and closed at once, nothing sent."""
        if self.ctx.left():
            self._reconnects(count)

    def _reconnects(self, count: int) -> None:
        self.log.append(f"{count} quick connect/close cycles")
        for _ in range(count):
            self._open("quick")
            self.conns.pop("quick").close("quick reconnect")
            self.sequence.append({"close": "quick"})

    @rule(name=st.sampled_from(("command", "stream")))
    def reconnect(self, name: str) -> None:
        if self.ctx.left():
            self._reopen(name, "reconnect")

    def teardown(self) -> None:
        for name, conn in self.conns.items():
            conn.close("end of session")
            self.sequence.append({"close": name})
        live = self.executor.check_alive()
        if not alive(live):
            self._fail(Finding(Verdict.FAIL, "R2", "R2: after the session the box still answers a fresh "
                               "connection", live.describe(), "R2/session"), FuzzCase("liveness", "R2", b"", "liveness"))


def machine_for(ctx: SessionContext) -> type[IsightSession]:
    """The session machine of one campaign: :class:`IsightSession` with its context and malformed-frame rule."""
    s = ctx.strategies
    cases = s.cases(tuple(c for c in MALFORMED if c in s.categories()))
    malformed = rule(case=cases, on=st.sampled_from(("command", "stream")))(IsightSession.malformed)
    return type("IsightSession", (IsightSession,), {"ctx": ctx, "malformed": malformed})


__all__ = ["MALFORMED", "IsightSession", "KnownFailure", "SessionContext", "StatefulFailure", "StatefulHang",
           "machine_for"]
