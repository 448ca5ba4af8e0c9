"""A: actions and answers (one answer per request in order, answer shape, error codes,
NONE, frames that are not requests).

CycleOn/CycleOff change the box's shared cycle state; every case that sends them
leaves the box idle again (CycleOff last), and judges CycleOn from a known state
(CycleOff first: CycleOn twice MAY be an error, S3).
"""

from __future__ import annotations

import time

import pytest

from conformance.protocol import (
    ACTION_ERROR,
    Action,
    Block,
    Codec,
    ErrorCode,
    Frame,
    Header,
    Profile,
    codec_for,
    encode,
    encode_raw,
    header_field_bytes,
    peek_header,
    request,
)
from conformance.protocol.answers import Cycle
from conformance.suite import (
    NOT_ANSWERED,
    NOT_OK,
    Answer,
    CaseContext,
    Closed,
    Expect,
    Level,
    Malformed,
    Outcome,
    Requirement,
    Silence,
    Skip,
    TcpConnection,
    answered,
    answered_allowed,
    case,
    reply_signature,
)

# -- the family's helpers: Helpers of the A cases (conformance/cases/actions.py): request sequences, answer shapes, malformed request sets, frames that are not requests.
POSE, REG, TOL = Action.POSE, Action.REGISTER_POSE, Action.TOLERANCE

ON, OFF, NONE = Action.CYCLE_ON, Action.CYCLE_OFF, Action.NONE

#: A1-01/A1-02: what a sequence of requests is judged by
SEQUENCE = {
    "order": Requirement(("A1",), "every well-formed request is answered with exactly one frame, in request order"),
    "once": Requirement(("A1",), "exactly one answer per request"),
    "taken": Requirement(("A1",), "the box answers every request"),
}


def mixed_requests(codec: Codec) -> list[Frame]:
    """20 mixed requests, no two neighbours with the same action (a duplicate shows)."""
    p = lambda n: request(POSE, codec.pose_blocks([(1.0 + i, 2.0, 3.0, 4.0, 5.0, 6.0) for i in range(n)]))  # noqa: E731
    r = request(REG, codec.pose_blocks([(10.0, 20.0, 30.0, 0.0, 90.0, 180.0)]))
    t = lambda n: request(TOL, codec.tolerance_blocks([0.5 * (i + 1) for i in range(n)]))  # noqa: E731
    n = request(NONE)
    return [n, p(1), t(1), r, n, request(ON), p(1), t(1), p(3), n,
            r, p(1), t(2), n, p(1), request(OFF), p(2), n, t(1), n]


def action_of(outcome: Outcome) -> int | None:
    """The action byte of what the box sent (an answer, or malformed bytes with a readable header)."""
    if isinstance(outcome, Answer):
        return int(outcome.frame.action)
    if isinstance(outcome, Malformed) and outcome.error.header is not None:
        return outcome.error.header.action
    return None


def name(action: int | None) -> str:
    try:
        return Action(action).name if action is not None else "nothing"
    except ValueError:
        return f"0x{action:02X}"


def judge_sequence(isight: CaseContext, conn: TcpConnection, frames: list[Frame], outcomes: list[Outcome], sent: bytes) -> None:
    for i, (frame, outcome) in enumerate(zip(frames, outcomes)):
        got = action_of(outcome)
        if got != frame.action:
            before = ", ".join(name(action_of(o)) for o in outcomes[max(0, i - 2): i + 1])
            raise isight.broken("order", expected=f"answer {i + 1} of {len(frames)} echoes {frame.action.name}",
                                observed=f"{outcome.describe()} (answers {max(1, i - 1)}..{i + 1}: {before})",
                                sent=sent, received=isight.transcript.received(conn.conn_id),
                                signature=reply_signature(outcome, frame.action))
    extra = conn.drain(isight.settings.settle_s)
    if any(not isinstance(o, Closed) for o in extra):
        raise isight.broken("once", expected=f"{len(frames)} answers and nothing more",
                            observed="after them: " + "; ".join(o.describe() for o in extra),
                            sent=sent, received=isight.transcript.received(conn.conn_id))


def shape_problems(raw: bytes, action: int) -> list[str]:
    problems = []
    head = peek_header(raw)
    if head is None:
        return [f"{len(raw)} bytes, expected 14"]
    if not head.is_answer:
        problems.append(f"transfer type {head.transfer_type:02x}, expected 10 (F3)")
    if head.action != action:
        problems.append(f"action {head.action:02x}, expected the request's {action:02x}")
    shape = b"".join(header_field_bytes(raw, f) for f in ("block_type", "block_count", "block_length"))
    if shape != b"\x00\x00\x00\x00":
        problems.append(f"block type/N/L {shape.hex(' ')}, expected 00 00 00 00")
    if len(raw) != 14:
        problems.append(f"{len(raw)} bytes, expected 14")
    return problems


A2_ACTIONS = [
    ("none", [NONE]), ("cycle-on-off", [OFF, ON, OFF]), ("pose", [POSE]), ("register-pose", [REG]),
    ("tolerance", [TOL]), ("malformed-pose", [None]),
]


def malformed_set(action: Action, profile: Profile) -> list[tuple[str, bytes]]:
    """Three parse errors (B3, B5 length, B5 count) for a 23/24/25 request."""
    first, third = codec_for(profile).block_index(0), codec_for(profile).block_index(2)
    pose = action in (POSE, REG)
    btype, blen = (1, 25) if pose else (2, 5)
    block = lambda i: bytes([i]) + bytes(blen - 1)  # noqa: E731
    return [
        ("indexes with a gap", encode_raw(Header(action=action, block_type=btype, block_count=2, block_length=blen),
                                          block(first) + block(third), profile=profile)),
        (f"block length {blen - 1}", encode_raw(Header(action=action, block_type=btype, block_count=1, block_length=blen - 1),
                                                block(first)[:-1], profile=profile)),
        ("no blocks (N=0)", encode_raw(Header(action=action, block_type=btype, block_count=0, block_length=blen),
                                       profile=profile)),
    ]


NOT_REQUESTS: list[tuple[str, dict[str, int], str]] = [
    ("start-fffe", {"start_word": 0xFFFE}, ""),
    ("start-feff", {"start_word": 0xFEFF}, ""),
    ("start-0000-pose", {"start_word": 0x0000}, "pose"),
    ("version-0000", {"version": 0x0000}, ""),
    ("version-0002", {"version": 0x0002}, ""),
    ("version-0100", {"version": 0x0100}, ""),
    ("version-ffff-pose", {"version": 0xFFFF}, "pose"),
    ("transfer-00", {"transfer_type": 0x00}, ""),
    ("transfer-02", {"transfer_type": 0x02}, ""),
    ("transfer-10", {"transfer_type": 0x10}, ""),
    ("transfer-11-pose", {"transfer_type": 0x11}, "pose"),
    ("transfer-ff", {"transfer_type": 0xFF}, ""),
    ("action-03", {"action": 0x03}, ""),
    ("action-04", {"action": 0x04}, ""),
    ("action-10-pose", {"action": 0x10}, "pose"),
    ("action-22", {"action": 0x22}, ""),
    ("action-28", {"action": 0x28}, ""),
    ("action-80", {"action": 0x80}, ""),
    ("action-ff", {"action": 0xFF}, ""),
]


def not_request(fields: dict[str, int], body: str, isight: CaseContext) -> bytes:
    base: dict[str, int] = {"action": ON}
    if body == "pose":
        block = encode(request(POSE, isight.codec.pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, 6.0)])),
                       isight.profile)[12:-2]
        base = {"action": POSE, "block_type": 1, "block_count": 1, "block_length": 25}
        return encode_raw(Header(**{**base, **fields}), block, profile=isight.profile)
    return encode_raw(Header(**{**base, **fields}), profile=isight.profile)


def type03_answer(action: Action, **_: object) -> Expect:
    def seems_e(o: Outcome) -> bool:
        header = o.error.header if isinstance(o, Malformed) else None
        return header is not None and header.action == action and header.block_type == 0x03

    return Expect("a type-03 block answer that does not parse", seems_e)


# -- the cases

# -- A1: one answer per request, in order ------------------------------------------------------


@case("A1-01", ["A1", "S6", "R4"], Level.MUST, "20 pipelined mixed requests are answered once each, in order",
      "20 answers whose actions follow the requests' order, and nothing after them", checks=SEQUENCE)
def test_pipelined_order(isight: CaseContext) -> None:
    frames = mixed_requests(isight.codec)
    data = b"".join(encode(f, isight.profile) for f in frames)
    conn = isight.connect()
    start = time.monotonic()
    if not conn.send(data, f"{len(frames)} requests in one send: " + " ".join(f.action.name for f in frames)):
        raise isight.broken("taken", expected="the requests to be taken", observed="the box closed the connection",
                            sent=data)
    outcomes: list[Outcome] = []
    for _ in frames:
        outcome = conn.next_outcome(since=start)
        outcomes.append(outcome)
        if isinstance(outcome, (Silence, Closed)):
            break
        isight.latencies_ms.append(outcome.latency_s * 1000)
    outcomes += [Silence(0.0)] * (len(frames) - len(outcomes))
    judge_sequence(isight, conn, frames, outcomes, data)


@case("A1-02", ["A1"], Level.MUST, "Requests sent one at a time are answered once each",
      "each request's next frame is its own answer; nothing follows the last one", checks=SEQUENCE)
def test_lockstep_once(isight: CaseContext) -> None:
    frames = mixed_requests(isight.codec)
    conn = isight.connect()
    outcomes: list[Outcome] = []
    for frame in frames:
        outcome = conn.request(frame, f"{frame.action.name} request")
        outcomes.append(outcome)
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)
        if action_of(outcome) != frame.action:
            break
    outcomes += [Silence(0.0)] * (len(frames) - len(outcomes))
    judge_sequence(isight, conn, frames, outcomes, isight.transcript.sent(conn.conn_id))


# -- A2: the shape of an answer -----------------------------------------------------------------


@case("A2-01", ["A2", "F3"], Level.MUST, "Answers carry transfer type 10, echo the action and carry no blocks",
      "every answer's bytes 4..9 are 10, the action, 00, 00, 00 00, and it is 14 bytes long",
      checks={"shape": Requirement(("A2",), "an answer has transfer type 10, echoes the action and carries no blocks"),
              "answered": Requirement(("A1",), "the {action.name} request is answered",
                                      accept=lambda action, **_: answered(action))})
@pytest.mark.parametrize("actions", [a for _, a in A2_ACTIONS], ids=[i for i, _ in A2_ACTIONS])
def test_answer_shape(isight: CaseContext, actions: list[Action | None]) -> None:
    conn = isight.connect()
    for action in actions:
        if action is None:  # an error answer must have the same shape (A2 covers every answer)
            action = POSE
            bad = encode_raw(Header(action=POSE, block_type=1, block_count=1, block_length=24), bytes(24), profile=isight.profile)
            outcome = isight.send_malformed(bad, "pose request with L=24 (parse error)", conn=conn)
            if isinstance(outcome, (Silence, Closed)):
                isight.inform(f"the box did not answer the malformed pose (it {outcome.describe()}): no error answer to inspect")
                return
        else:
            blocks: tuple[Block, ...] = ()
            if action in (POSE, REG):
                blocks = isight.codec.pose_blocks([(1.0, 2.0, 3.0, 4.0, 5.0, float(action))])
            elif action is TOL:
                blocks = isight.codec.tolerance_blocks([0.5])
            outcome = conn.request(request(action, blocks), f"{action.name} request")
        sent = isight.transcript.sent(conn.conn_id)
        if isinstance(outcome, Malformed):
            raw = outcome.error.raw
            problems = shape_problems(raw, action) if len(raw) >= 12 else ["not a frame"]
            if not problems:  # the shape is right; what is wrong (e.g. A4) is judged elsewhere
                continue
            raise isight.broken("shape", expected="10 | action | 00 | 00 | 00 00",
                                observed="; ".join(problems) or str(outcome.error), sent=sent, received=raw,
                                signature=reply_signature(outcome, action))
        isight.judge(outcome, "answered", sent=sent, action=action)
        assert isinstance(outcome, Answer)
        problems = shape_problems(outcome.raw, action)
        if problems:
            raise isight.broken("shape", expected="10 | action | 00 | 00 | 00 00 (14 bytes)", observed="; ".join(problems),
                                sent=sent, received=outcome.raw, signature=reply_signature(outcome, action))


# -- A3: error codes ----------------------------------------------------------------------------


@case("A3-01", ["A3", "B3", "B5"], Level.MUST, "Malformed 23/24/25 requests get the action's error, never 0000",
      "on one connection, each is not answered 0000 (MUST) and is answered 1001 (23/24) or 1002 (25) (SHOULD)",
      checks={"no-0000": Requirement(("A3",), "a {action.name} request with {what} MUST NOT be answered 0000", accept=NOT_OK),
              "code": Requirement(("A3",), "a {action.name} request with {what} SHOULD be answered {error:04X}",
                                  level=Level.SHOULD,
                                  accept=lambda action, **_: answered(action, [ACTION_ERROR[action]]))},
      shares_box=True)
@pytest.mark.parametrize("action", [POSE, REG, TOL], ids=["pose", "register-pose", "tolerance"])
def test_parse_error_codes(isight: CaseContext, action: Action) -> None:
    conn = isight.connect("malformed")
    results: list[tuple[str, bytes, Outcome]] = []
    for what, bad in malformed_set(action, isight.profile):
        if conn.closed_by_peer is not None:
            conn = isight.connect("malformed (reconnected after the box closed)")
        results.append((what, bad, isight.send_malformed(bad, f"{action.name} request with {what}", conn=conn)))
    for what, bad, outcome in results:
        isight.judge(outcome, "no-0000", sent=bad, what=what)
    for what, bad, outcome in results:  # the SHOULDs after every MUST
        isight.judge(outcome, "code", sent=bad, what=what, error=ACTION_ERROR[action])


@case("A3-02", ["A3", "S2"], Level.MUST, "CycleOn is answered 0000 or 0001, CycleOff 0000 or 0002",
      "from an idle box: CycleOn answered 0000 (or 0001: not ready, then INCONCLUSIVE); CycleOff then answered 0000 or 0002",
      checks={"idle": Requirement(("S3",), "a CycleOff first brings the box to idle (its answer is not judged)",
                                  inconclusive=NOT_ANSWERED, inconclusive_text="could not bring the box to idle"),
              "on": Requirement(("S2", "A3"), "CycleOn is answered 0000, or 0001 when not ready", accept=answered_allowed(ON, Cycle.IDLE),
                                inconclusive=answered(ON, [ErrorCode.NOT_READY]),
                                inconclusive_text="S2: CycleOn answered 0001 (box not ready): CycleOff after it is not judged"),
              "off": Requirement(("A3",), "CycleOff is answered 0000, or 0002 when the detection could not be closed",
                                 accept=answered_allowed(OFF, Cycle.ON), informational=answered(OFF, [ErrorCode.CYCLE_OFF_FAILED]),
                                 informational_text="CycleOff answered 0002: the box could not close the detection (A3)")})
def test_cycle_codes(isight: CaseContext) -> None:
    conn = isight.connect()
    isight.judge(conn.request(request(OFF), "CycleOff first, so the box is idle (its answer is not judged, S3)"), "idle")
    isight.judge(conn.request(request(ON), "CycleOn request"), "on", sent=isight.transcript.sent(conn.conn_id))
    isight.judge(conn.request(request(OFF), "CycleOff request"), "off", sent=isight.transcript.sent(conn.conn_id))


# -- A4: NONE -----------------------------------------------------------------------------------


@case("A4-01", ["A4"], Level.MUST, "NONE (action 00) is answered NONE with 0000",
      "each NONE request, on a fresh connection and three in a row on one connection, is answered NONE 0000",
      checks={"": Requirement(("A4",), "action 00 is answered with action 00 and error 0000", accept=answered_allowed(NONE))},
      shares_box=True)
def test_none_answered(isight: CaseContext) -> None:
    isight.judge(isight.exchange(request(NONE), "NONE request on a fresh connection"))
    conn = isight.connect()
    for i in range(3):
        outcome = conn.request(request(NONE), f"NONE request {i + 1}/3")
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)
        isight.judge(outcome, sent=encode(request(NONE), isight.profile))


# -- A5: frames that are not requests -----------------------------------------------------------


@case("A5-01", ["A5", "R1", "F1", "F2", "F3"], Level.MUST, "A frame that is not a request is never answered 0000",
      "silence, a non-zero error, or a close; never 0000",
      checks={"": Requirement(("A5",), "a frame that is not a request MUST NOT be answered 0000", accept=NOT_OK)})
@pytest.mark.parametrize("fields,body", [c[1:] for c in NOT_REQUESTS], ids=[c[0] for c in NOT_REQUESTS])
def test_not_a_request(isight: CaseContext, fields: dict[str, int], body: str) -> None:
    bad = not_request(fields, body, isight)
    isight.judge(isight.send_malformed(bad, "not a request: " + ", ".join(f"{k}={v:#x}" for k, v in fields.items())))


@case("A5-02", ["A5", "R1", "E2", "E3"], Level.MUST, "Without extension E, actions 26 and 27 are unknown and never answered 0000",
      "SKIP when the box implements E; else silence, a non-zero error, or a close to 26 and 27; never 0000",
      checks={"": Requirement(("A5",), "without E, action {action:02x} is unknown and MUST NOT be answered 0000", accept=NOT_OK,
                              inconclusive=type03_answer,
                              inconclusive_text="the box answers {action:02x} with a type-03 block (it seems to implement "
                                                "E), but the answer does not parse under this run's profile; check the "
                                                "profile, e.g. --first-index")})
@pytest.mark.parametrize("action", [Action.PROG_IDX, Action.VISION_RESULT], ids=["26-prog-idx", "27-vision-result"])
def test_extension_actions_unknown(isight: CaseContext, action: Action) -> None:
    if isight.settings.extension == "off":
        raise Skip("--extension off: whether the box implements E is not known, so 26/27 are not judged as unknown")
    if isight.session.detect_extension(isight.transcript):
        raise Skip(f"the box implements extension E ({isight.session.extension_how}): 26/27 are known actions")
    blocks = isight.codec.value_blocks([7]) if action is Action.PROG_IDX else ()
    bad = encode(request(action, blocks), isight.profile)
    isight.judge(isight.send_malformed(bad, f"{action.name} ({action:#04x}) request to a box without extension E"))


@case("A5-03", ["A5", "R6"], Level.MAY, "What the box does with frames that are not requests",
      "recorded: silence, an error or a close for each kind, and whether the next valid request is answered")
def test_not_a_request_behaviour(isight: CaseContext) -> None:
    kinds = [("garbage bytes", b"\x00\x11\x22\x33\x44\x55\x66\x77\x88\x99\xaa\xbb\xcc\xdd"),
             ("wrong start word", not_request({"start_word": 0xFFFE}, "", isight)),
             ("version 00 02", not_request({"version": 0x0002}, "", isight)),
             ("transfer type 10", not_request({"transfer_type": 0x10}, "", isight)),
             ("unknown action 03", not_request({"action": 0x03}, "", isight))]
    conn = isight.connect("malformed")
    seen = []
    for what, bad in kinds:
        if conn.closed_by_peer is not None:
            conn = isight.connect("malformed (reconnected after the box closed)")
        outcome = isight.send_malformed(bad, what, conn=conn)
        did = "no answer" if isinstance(outcome, Silence) else outcome.describe()
        probe = isight.last_probe.describe() if isight.last_probe is not None else "not sent"
        seen.append(f"{what}: {did}, the valid request behind it {probe}")
    isight.details["not_requests"] = seen
    isight.inform("; ".join(seen))
