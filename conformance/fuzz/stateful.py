"""Stateful fuzzing: a hypothesis state machine plays a session on a command and a stream connection.

Rules: NONE, CycleOn, CycleOff, poses on the stream connection (one at a time or
pipelined, S6), register poses and tolerances on the command connection, ProgIdx and
the result request (only when the box implements extension E), malformed frames from
the frame strategies on either connection (each followed by a probe), and reconnects
of either connection. The model keeps the box's cycle state (S2/S3): CycleOn on an
idle box is answered 0000 or 0001, CycleOff on a running cycle 0000 or 0002; after
anything that may have changed it the state is unknown and either answer is fine.
Every answer is judged by the frame oracle (:mod:`.oracle`); teardown checks liveness
on a fresh connection (R2).

A failure is shrunk by hypothesis to the shortest session that still fails and
written as a vector file (the request that failed), an ``isight-sequence-1`` file
replaying the whole session (``isight-conformance run --sequence FILE``) and a pcap.

:func:`run_stateful` is given what it needs (the configuration, the strategies, the seed,
a budget and the next failure's number) and returns a :class:`StatefulResult` (sessions
run, steps, failures, why it stopped) that the campaign adds to its own counts.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from hypothesis import HealthCheck, Phase, Verbosity, settings
from hypothesis import strategies as st
from hypothesis.errors import Flaky
from hypothesis.stateful import RuleBasedStateMachine, precondition, rule, run_state_machine_as_test

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence
from ..harness.target import Unreachable
from ..harness.transcript import Transcript
from ..protocol import BLOCK_LEN, Action, BlockType, Header, Transport, codec_for
from ..protocol.answers import SENDABLE_RESULTS
from ..suite.verdicts import Verdict
from .config import CampaignConfig
from .evidence import Failure, clauses_of, write_pcap, write_sequence, write_vectors
from .executor import Executor, FuzzConnection, alive
from .oracle import Expectation, Finding, Rule, judge
from .strategies import FuzzCase, Strategies, _finite

#: Steps per session (hypothesis's stateful_step_count) and sessions per hypothesis run.
STEPS = 25
RUNS_PER_CHUNK = 10
#: Frame categories the machine interleaves as malformed input (stream-safe: no truncation at EOF, no UDP).
MALFORMED = ("F1-start-word", "F2-version", "F3-direction", "A5-unknown-action", "B5-shape", "B3-index",
             "B4-floats", "F5-trailing", "F5-spliced", "F6-check", "R5-oversized", "mutation", "F1-garbage")


@dataclass
class StatefulResult:
    """What the session runs did: the campaign adds the counts and the failures to its own."""

    runs: int = 0
    steps: int = 0
    failures: list[Failure] = field(default_factory=list)
    stopped: str = ""  # why the runs ended before the budget did: "failure", "hang", "flaky" ("": budget spent)


@dataclass
class _Run:
    """The state the session machine shares with :func:`run_stateful`."""

    budget: Callable[[int], bool]  # may another step run, after this many steps?
    result: StatefulResult = field(default_factory=StatefulResult)
    shrinking: bool = False  # hypothesis is shrinking a failure: every step runs

    def left(self) -> bool:
        return self.shrinking or self.budget(self.result.steps)


class StatefulFailure(AssertionError):
    def __init__(self, finding: Finding, machine: Any, case: FuzzCase) -> None:
        super().__init__(finding.describe())
        self.finding = finding
        self.steps = list(machine.log)
        self.sequence = list(machine.sequence)
        self.transcript: Transcript = machine.tr
        self.case = case


class StatefulHang(BaseException):
    """A session failure where the box stayed silent for time_out: reported as found, not shrunk
    (every shrink step would wait time_out again). A BaseException, so hypothesis lets it through."""

    def __init__(self, failure: StatefulFailure) -> None:
        super().__init__(str(failure))
        self.failure = failure


def _codes(codes: set[int] | frozenset[int] | None) -> Any:
    return "answered" if codes is None else {"errors": [f"{c:04X}" for c in sorted(codes)]}


def machine_for(cfg: CampaignConfig, strategies: Strategies, run: _Run) -> type[RuleBasedStateMachine]:
    profile = cfg.profile
    codec = codec_for(profile)
    malformed_cases = strategies.cases(tuple(c for c in MALFORMED if c in strategies.categories()))
    first = profile.first_index
    order = ">" if profile.float_byte_order == "big" else "<"
    stream_target = cfg.stream_target or cfg.target

    def finite(raw: bytes) -> bytes:
        return _finite(raw, "big" if order == ">" else "little")

    class IsightSession(RuleBasedStateMachine):
        """One robot session against the box (see the module docstring)."""

        def __init__(self) -> None:
            super().__init__()
            self.tr = cfg.transcript if cfg.transcript is not None else Transcript(case_id="FUZZ-stateful")
            self.log: list[str] = []
            self.sequence: list[dict[str, Any]] = []
            self.conns: dict[str, FuzzConnection] = {}
            self.executor = Executor(cfg.target, profile, self.tr, extension=cfg.extension, settle_s=cfg.settle_s)
            self.cycle: bool | None = None
            run.result.runs += 1
            for name in ("command", "stream"):
                self._open(name)
            # a known state to start from: whatever CycleOff gets, the cycle is then off (or unknown)
            o = self._send("command", codec.encode_raw(Header(action=Action.CYCLE_OFF)), Action.CYCLE_OFF, None,
                           "start from a known state: CycleOff")
            self.cycle = False if isinstance(o, Answer) and o.frame.error_code == 0 else None

        # -- plumbing ------------------------------------------------------------------------
        def _open(self, name: str) -> None:
            conn = FuzzConnection(self.tr, stream_target if name == "stream" else cfg.target, profile, name)
            try:
                conn.connect()
            except Unreachable as exc:
                self._fail(Finding(Verdict.FAIL, "R2", "R2/S4: the box accepts the robot's connections",
                                   str(exc)), FuzzCase("connect", "R2", b"", f"open {name}"))
            self.conns[name] = conn
            self.sequence.append({"open": name, "target": "stream" if name == "stream" else "command"})
            self.log.append(f"open {name}")

        def _fail(self, finding: Finding, case: FuzzCase, hang: bool = False) -> None:
            if hang and not run.shrinking:
                raise StatefulHang(StatefulFailure(finding, self, case))
            run.shrinking = True  # from now on every step runs: hypothesis is shrinking
            raise StatefulFailure(finding, self, case)

        def _budget(self) -> bool:
            return run.left()

        def _send(self, name: str, data: bytes, action: Action, ok: set[int] | frozenset[int] | None,
                  what: str, values: frozenset[int] | None = None) -> Outcome:
            conn = self.conns[name]
            self.log.append(f"{what} on {name}")
            step: dict[str, Any] = {"raw": data.hex(), "on": name, "expect": _codes(ok), "note": what}
            if values is not None:
                step["expect"] = dict(step["expect"] if isinstance(step["expect"], dict) else {}, values=sorted(values))
            self.sequence.append(step)
            outcome = conn.request(data, what)
            run.result.steps += 1
            exp = Expectation(Rule.ANSWER, "", int(action), what, frozenset(ok) if ok is not None else None,
                              values=values)
            answers = [outcome] if isinstance(outcome, (Answer, Malformed)) else []
            judgement = judge((exp,), answers, outcome if isinstance(outcome, (Closed, Silence)) else None, profile)
            case = FuzzCase("session", "", data, what, expects=(exp,))
            for finding in judgement.failures:
                self._fail(finding, case, hang=isinstance(outcome, Silence))
            if isinstance(outcome, (Closed, Silence)):
                self._open(name)
            return outcome

        def _request(self, name: str, action: Action, blocks: bytes = b"", n: int = 0,
                     block_type: BlockType = BlockType.EMPTY) -> bytes:
            header = Header(action=action, block_type=block_type, block_count=n, block_length=BLOCK_LEN[block_type])
            return codec.encode_raw(header, blocks)

        def _poses(self, raw: bytes) -> tuple[bytes, int]:
            raw = finite(raw)
            n = len(raw) // 24
            return b"".join(bytes([(first + i) & 0xFF]) + raw[i * 24 : (i + 1) * 24] for i in range(n)), n

        # -- rules ---------------------------------------------------------------------------
        @rule()
        def none(self) -> None:
            if self._budget():
                self._send("command", self._request("command", Action.NONE), Action.NONE, {0}, "NONE")

        @rule()
        def cycle_on(self) -> None:
            if not self._budget():
                return
            ok = {0, 1} if self.cycle is False else None
            o = self._send("command", self._request("command", Action.CYCLE_ON), Action.CYCLE_ON, ok, "CycleOn")
            code = o.frame.error_code if isinstance(o, Answer) else None
            self.cycle = True if code == 0 else (self.cycle if code == 1 else None)

        @rule()
        def cycle_off(self) -> None:
            if not self._budget():
                return
            ok = {0, 2} if self.cycle is True else None
            o = self._send("command", self._request("command", Action.CYCLE_OFF), Action.CYCLE_OFF, ok, "CycleOff")
            code = o.frame.error_code if isinstance(o, Answer) else None
            self.cycle = False if code == 0 else (self.cycle if code == 2 else None)

        @rule(raw=st.binary(min_size=24, max_size=72))
        def pose(self, raw: bytes) -> None:
            if self._budget():
                body, n = self._poses(raw)
                data = self._request("stream", Action.POSE, body, n, BlockType.POSE)
                self._send("stream", data, Action.POSE, {0}, f"pose ×{n} (S3)")

        @rule(count=st.integers(2, 16), raw=st.binary(min_size=24, max_size=24))
        def pipelined_poses(self, count: int, raw: bytes) -> None:
            """S6/R4: ``count`` poses in one write, then their answers, in order."""
            if not self._budget():
                return
            body, _ = self._poses(raw)
            one = self._request("stream", Action.POSE, body, 1, BlockType.POSE)
            conn = self.conns["stream"]
            what = f"{count} pipelined poses in one write (S6, R4)"
            self.log.append(f"{what} on stream")
            pose = struct.unpack(order + "6f", body[1:25])
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
            run.result.steps += count
            for finding in judge(case.expects, outcomes, end, profile).failures:
                self._fail(finding, case, hang=isinstance(end, Silence))

        @rule(raw=st.binary(min_size=24, max_size=72))
        def register_pose(self, raw: bytes) -> None:
            if self._budget():
                body, n = self._poses(raw)
                data = self._request("command", Action.REGISTER_POSE, body, n, BlockType.POSE)
                self._send("command", data, Action.REGISTER_POSE, {0}, f"register pose ×{n}")

        @rule(raw=st.binary(min_size=4, max_size=12))
        def tolerance(self, raw: bytes) -> None:
            if not self._budget():
                return
            raw = finite(raw[: len(raw) // 4 * 4])
            n = len(raw) // 4
            body = b"".join(bytes([(first + i) & 0xFF]) + raw[i * 4 : (i + 1) * 4] for i in range(n))
            data = self._request("command", Action.TOLERANCE, body, n, BlockType.TOLERANCE)
            self._send("command", data, Action.TOLERANCE, {0}, f"tolerance ×{n}")

        @precondition(lambda self: cfg.extension)
        @rule(value=st.integers(-(2**31), 2**31 - 1))
        def prog_idx(self, value: int) -> None:
            if self._budget():
                body = bytes([first]) + struct.pack(order + "i", value)
                data = self._request("command", Action.PROG_IDX, body, 1, BlockType.VALUE)
                self._send("command", data, Action.PROG_IDX, {0, 409}, f"ProgIdx {value} (E2)",
                           values=frozenset({value, 409}))

        @precondition(lambda self: cfg.extension)
        @rule()
        def vision_result(self) -> None:
            if self._budget():
                self._send("command", self._request("command", Action.VISION_RESULT), Action.VISION_RESULT, None,
                           "result request (E3)", values=frozenset(SENDABLE_RESULTS))

        @rule(case=malformed_cases, on=st.sampled_from(("command", "stream")))
        def malformed(self, case: FuzzCase, on: str) -> None:
            if not self._budget():
                return
            self.log.append(f"malformed on {on}: {case.describe()}")
            self.sequence.append({"raw": case.wire.hex(), "on": on, "probe": True, "note": case.describe()[:200]})
            result = self.executor.exchange(self.conns[on], case, f"malformed: {case.describe()}")
            run.result.steps += 1
            for finding in result.judgement.failures:
                self._fail(finding, case, hang=isinstance(result.end, Silence))
            if any(e.action in (Action.CYCLE_ON, Action.CYCLE_OFF) for e in case.expects):
                self.cycle = None
            if result.conn < 0:  # the box closed or hung (allowed after bytes that are not a request)
                self.conns[on].abort("reopened after the box closed or hung")
                self._open(on)

        @rule(name=st.sampled_from(("command", "stream")))
        def reconnect(self, name: str) -> None:
            if self._budget():
                self.conns[name].close("reconnect")
                self.sequence.append({"close": name})
                self.log.append(f"close {name}")
                self._open(name)

        def teardown(self) -> None:
            for name, conn in self.conns.items():
                conn.close("end of session")
                self.sequence.append({"close": name})
            live = self.executor.check_alive()
            if not alive(live):
                self._fail(Finding(Verdict.FAIL, "R2", "R2: after the session the box still answers a fresh "
                                   "connection", live.describe()), FuzzCase("liveness", "R2", b"", "liveness"))

    return IsightSession


def run_stateful(cfg: CampaignConfig, strategies: Strategies, campaign_seed: int, budget: Callable[[int], bool],
                 number: int) -> StatefulResult:
    """Session runs while ``budget(steps)`` allows (or until a failure is found, written as failure ``number``)."""
    run = _Run(budget)
    machine = machine_for(cfg, strategies, run)
    result = run.result
    chunk = 0
    while run.budget(result.steps):
        machine._hypothesis_internal_use_seed = campaign_seed * 7919 + chunk  # type: ignore[attr-defined]
        hyp = settings(
            max_examples=RUNS_PER_CHUNK, stateful_step_count=STEPS, deadline=None, database=cfg.database,
            phases=[Phase.generate, Phase.shrink] if chunk else [Phase.reuse, Phase.generate, Phase.shrink],
            suppress_health_check=list(HealthCheck), report_multiple_bugs=False, derandomize=False,
            verbosity=Verbosity.quiet, print_blob=False,
        )
        run.shrinking = False
        try:
            run_state_machine_as_test(machine, settings=hyp)
        except StatefulFailure as exc:
            result.failures.append(_record(cfg, campaign_seed, number, exc))
            result.stopped = "failure"
            return result
        except StatefulHang as exc:  # not shrunk: each step would wait time_out
            result.failures.append(_record(cfg, campaign_seed, number, exc.failure, shrunk=False))
            result.stopped = "hang"
            return result
        except Flaky as exc:
            cfg.log(f"fuzz: a session failure did not reproduce when hypothesis replayed it ({type(exc).__name__})")
            result.stopped = "flaky"
            return result
        chunk += 1
    return result


def _record(cfg: CampaignConfig, campaign_seed: int, number: int, exc: StatefulFailure, shrunk: bool = True) -> Failure:
    """The session failure's vector file (the failing request), sequence file and pcap, and a line in the log."""
    name = f"{cfg.name}-{number:03d}"
    f = exc.finding
    how = "shrunk by hypothesis" if shrunk else "not shrunk: the box hung, each shrink step would wait time_out"
    message = f"{f.requirement}; the box {f.observed} (session of {len(exc.steps)} steps, {how})"
    failure = Failure(number, "stateful", clauses_of(exc.case, [f.clause]), message, [exc.case] if exc.case.data else [],
                      shrunk=shrunk, steps=exc.steps)
    desc = f"isight-conformance fuzz: session failure {number} against {cfg.target} (seed {campaign_seed})"
    if failure.cases and cfg.report_dir is not None:
        failure.vector = write_vectors(cfg.report_dir / f"{name}.json", failure, cfg.profile, desc)
    if cfg.report_dir is not None:
        failure.sequence = write_sequence(cfg.report_dir / f"{name}.sequence.json", number, failure, exc.sequence)
    if cfg.capture != "off" and cfg.pcap_dir is not None:
        failure.pcap = write_pcap(exc.transcript, cfg.pcap_dir / f"{name}.pcapng")
    cfg.log(f"fuzz: FAIL {number} [{', '.join(failure.clauses)}] {message}\n      steps: "
            + "; ".join(exc.steps) + f"\n      sequence: {failure.sequence}"
            + (f"\n      vector: {failure.vector}" if failure.vector else "")
            + (f"\n      pcap: {failure.pcap}" if failure.pcap else ""))
    return failure


__all__ = ["STEPS", "StatefulFailure", "StatefulResult", "machine_for", "run_stateful", "write_sequence", "Transport"]
