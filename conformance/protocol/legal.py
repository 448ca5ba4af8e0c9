"""The legal-choice space: every point where docs/PROTOCOL.md lets an implementation choose (sans-I/O).

Each :class:`Choice` is one MAY, one **[decision]**, one "either … or" of the protocol, or
one freedom on the wire that the protocol leaves open (how an answer is written, how long
it takes below time_out, how bad bytes are framed), with its clauses and its alternatives.
``tester`` says how a tester meets it: ``"set"`` (it accepts every alternative and fails
none: a verdict never depends on which one a box or robot took) or ``"flag"`` (the
alternatives read the protocol differently; a profile flag tells the tester which one,
and ``flag`` names it for each non-default alternative).

``knob`` names the setting of the independent implementations in ``tests/impls`` that
takes exactly these alternatives (the box's :class:`Choices`, the robot's
``RobotChoices``); tests/unit/test_impls_legal.py fails when a row has an alternative that is
no knob value, or a knob has no row. docs/LEGAL-CHOICES.md is :func:`render_markdown`
(a test keeps it in step): ``python -m conformance.protocol.legal > docs/LEGAL-CHOICES.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

KINDS = ("MAY", "decision", "either-or", "wire")
SIDES = ("box", "robot")
TESTERS = ("set", "flag")


@dataclass(frozen=True)
class Choice:
    id: str
    side: str  # "box" or "robot"
    clauses: tuple[str, ...]
    kind: str  # one of KINDS
    question: str
    alternatives: tuple[str, ...]  # the first is the default of tests/impls
    tester: str  # "set" or "flag"
    knob: str  # the setting of tests/impls that takes these alternatives ("": none, see NO_KNOB)
    flags: dict[str, str] = field(default_factory=dict)  # alternative -> the profile flag a tester needs for it
    note: str = ""


def _c(id_: str, side: str, clauses: str, kind: str, question: str, alternatives: str, knob: str,
       note: str = "", flags: dict[str, str] | None = None) -> Choice:
    return Choice(id_, side, tuple(clauses.split()), kind, question, tuple(alternatives.split(" | ")),
                  "flag" if flags else "set", knob, dict(flags or {}), note)


_RESUME = "resume+1 | resume+5 | resume+12"
#: the note of a flag-decided row no implementation in tests/impls takes (their codec is big-endian, MODBUS)
NO_KNOB = "no knob: the independent implementations' codec has one reading; the suite's flag is tested elsewhere"
#: Every legal choice, box side first. The alternatives' first entry is the default of tests/impls.
CHOICES: tuple[Choice, ...] = (
    # -- R6: how bad bytes are framed, chosen per kind of bad field ---------------------------------------
    _c("framing-garbage", "box", "R6", "either-or",
       "bytes where a frame should start that are not FE FE (garbage between frames)",
       "scan | close", "framing_garbage",
       "scan: drop them and resume at the next FE FE (b); close the connection (c)"),
    _c("framing-version", "box", "R6 F2", "either-or", "a header with the start word but another version",
       f"{_RESUME} | close", "framing_version",
       "resume+k: reject the header, search the next FE FE from its k-th byte on (b; any k from 1 to 12); "
       "R6 (a) trusts only a header whose start word and version are right"),
    _c("framing-length", "box", "R6 R5 F5", "either-or",
       "a header announcing more block bytes than the largest legal frame (255 pose blocks)",
       f"{_RESUME} | close", "framing_length"),
    _c("framing-transfer", "box", "R6 F3", "either-or", "a header whose transfer type is not 01",
       f"trust | {_RESUME} | close", "framing_transfer",
       "trust: skip its announced length as one bad frame (a), then A5 says how it is answered"),
    _c("framing-action", "box", "R6 A5", "either-or", "a header with an unknown action",
       f"trust | {_RESUME} | close", "framing_action"),
    _c("framing-shape", "box", "R6 B5 A3", "either-or",
       "a request header whose block type, count or length does not fit its action",
       f"trust | {_RESUME}", "framing_shape",
       "either way it is answered as A3 says (its action's error for 23/24/25); closing instead breaks A3's "
       "SHOULD, so it is no alternative here"),
    # -- A5 / A3: refusals -------------------------------------------------------------------------------
    _c("not-a-request", "box", "A5", "MAY", "a frame that is not a request (taken whole or rejected)",
       "silent | error | close", "not_request"),
    _c("refusal-action", "box", "A5 A2", "either-or", "the action byte of a refusal (a non-zero error answer)",
       "echo | 00", "refusal_action",
       "A2's echo binds answers to requests; a frame that is not a request may be refused with action 00"),
    _c("refusal-code", "box", "A5", "MAY", "the error code of a refusal", "FFFF | 0001 | 1001",
       "refusal_code", "any non-zero code"),
    _c("malformed-blockless", "box", "A3", "either-or", "a malformed 00, 01 or 02 (no code is named)",
       "error | silent | close", "malformed_blockless",
       "error: 0001 for 01, 0002 for 02, FFFF for 00"),
    _c("malformed-extension", "box", "A3 E2 E3", "either-or", "a malformed 26 or 27 (no code is named)",
       "silent | 400", "malformed_ext", "400: ResultCode 400 (request not understood) in the block and the error"),
    _c("request-error-field", "box", "A3 F5", "wire", "a request whose (undefined) error field is not 0000",
       "accept | reject", "request_error_field", "reject: answered as a malformed request"),
    _c("tcp-check", "box", "F6", "decision", "what a TCP receiver accepts in the check field",
       "ignore | zero-or-crc", "tcp_check",
       "F6: a receiver SHOULD ignore it; accepting only 00 00 and the correct CRC is what --tcp-check "
       "zero-or-crc (the default) expects, so both are clean"),
    # -- S2 / S3: the cycle ------------------------------------------------------------------------------
    _c("cycle-scope", "box", "S3", "decision", "where the cycle state lives", "box | connection", "cycle_scope"),
    _c("cycle-on-twice", "box", "S3", "MAY", "CycleOn while a cycle is on", "0000 | 0001", "cycle_on_twice"),
    _c("cycle-off-idle", "box", "S3", "MAY", "CycleOff without CycleOn", "0000 | 0002", "cycle_off_idle"),
    _c("cycle-on-ready", "box", "S2", "either-or", "CycleOn answered 0000, or 0001 when the box is not ready",
       "ready | first-not-ready", "cycle_on_ready",
       "first-not-ready: the first CycleOn after start is answered 0001 (warming up); that cycle is inconclusive"),
    # -- E: the extension --------------------------------------------------------------------------------
    _c("extension", "box", "E1 E2 E3 E4 E5 A5", "either-or", "the extension (26/27)", "present | absent",
       "extension", "detected by --extension auto; absent: 26 and 27 are unknown actions (A5)"),
    _c("extension-refusal", "box", "A5 E1", "MAY", "26 and 27 at a box without the extension",
       "silent | error-echo | error-00 | close", "ext_refusal",
       "the A5 reactions to an unknown action; a refusal is not support"),
    _c("progidx-answer", "box", "E2", "either-or", "ProgIdx answered with the index (ready) or 409",
       "index | 409", "prog_idx"),
    _c("result-code", "box", "E3", "either-or", "the ResultCode of a result request",
       "1 | 2 | 10 | 20 | 202 | 409", "vision_result", "202 (busy) and 409 leave the result open"),
    _c("progidx-conflict", "box", "E2", "decision", "where a ProgIdx 409 travels", "block | error-code",
       "progidx_conflict", flags={"error-code": "--progidx-conflict error-code"}),
    # -- decisions a flag tells the tester ---------------------------------------------------------------
    _c("first-index", "box", "B3", "decision", "the index of the first block", "0 | 1", "first_index",
       flags={"1": "--first-index 1"}),
    _c("non-finite", "box", "B4", "decision", "NaN or infinity in a pose or tolerance",
       "reject | accept", "nan", "reject is the SHOULD; accept is clean only under --checking lenient",
       flags={"accept": "--checking lenient"}),
    _c("stream-port", "box", "S4", "decision", "where the stream connection goes", "same | separate",
       "stream_port", "separate: a second port serves the stream (and anything else)",
       flags={"separate": "--stream-target HOST:PORT"}),
    _c("byte-order", "box", "F4", "decision", "the byte order of the header's multi-byte fields", "big | little",
       "", NO_KNOB, flags={"little": "--byte-order little"}),
    _c("float-byte-order", "box", "B4 E1", "decision", "the byte order of float32 and int32 values",
       "big | little", "", NO_KNOB, flags={"little": "--float-byte-order little"}),
    _c("crc", "box", "F7 R7", "decision", "the UDP CRC-16 algorithm and its byte order",
       "modbus big | other crcmod algorithm or little", "", NO_KNOB,
       flags={"other crcmod algorithm or little": "--crc NAME --crc-byte-order little"}),
    _c("udp", "box", "F7 R7", "either-or", "TCP (or UDP): whether the box also serves UDP", "off | on", "udp",
       flags={"on": "--udp-target HOST:PORT"}),
    # -- the wire ----------------------------------------------------------------------------------------
    _c("answer-writes", "box", "R3 F5", "wire", "how an answer is written",
       "whole | bytes | pieces", "writer",
       "bytes: one byte per send; pieces: Nagle on, the header first and the rest after a pause"),
    _c("latency", "box", "T1 T2", "wire", "how long after its request an answer goes out (below time_out)",
       "0 | 2ms | 20ms | 100ms", "latency",
       "answers stay in request order and pipelined: a pose's latency does not grow with the stream"),
    _c("cycle-on-latency", "box", "T1 S2", "wire", "how long CycleOn takes (the detection getting ready)",
       "0 | 0.6 time_out", "cycle_on_latency"),
    # -- the robot ---------------------------------------------------------------------------------------
    _c("robot-pings", "robot", "A4 S1", "MAY", "NONE requests (pings) on the command connection",
       "0 | 1 | 3", "pings", "before the session and between its steps"),
    _c("robot-command-poses", "robot", "S1 B1", "MAY", "poses on the command connection (ISIGHT(3,35), (3,36))",
       "none | pose | register | both", "cmd_poses"),
    _c("robot-tolerances", "robot", "S1 B2 B5", "MAY", "tolerance requests on the command connection",
       "none | start | in-cycle | after-cycle", "tolerance_at", "any number of blocks"),
    _c("robot-tolerance-blocks", "robot", "B2 B5", "MAY", "the blocks of one tolerance request", "1 | 3 | 17",
       "tolerance_blocks"),
    _c("robot-cycles", "robot", "S1", "MAY", "CycleOn -> CycleOff pairs between stream on and stream off",
       "1 | 2 | 3", "cycles", "each CycleOn closed by its CycleOff before the next (several parts primed)"),
    _c("robot-writes", "robot", "R3 F5", "wire", "how a request is written", "whole | pieces | bytes",
       "writer", "pieces: the header first, the rest after a pause"),
    _c("robot-reads", "robot", "S6", "decision", "when the stream's answers are read", "as-they-come | late",
       "read_late", "late: in bursts every 0.5 s (pipelined)"),
    _c("robot-extension", "robot", "E4", "either-or", "the session: S1, or the revision's E4", "S1 | E4",
       "session", "detected by certify-robot's --extension auto: a session with ProgIdx (or 27) is judged E4"),
    _c("robot-rate", "robot", "T2", "decision", "the declared stream rate", "50 | 20 | 100", "rate",
       flags={"20": "--pose-rate 20", "100": "--pose-rate 100"}),
    _c("robot-time-out", "robot", "T1 E5", "decision", "time_out and vision_time_out (the robot's settings)",
       "5000 ms | other", "", NO_KNOB, flags={"other": "--time-out MS --vision-time-out MS"}),
)


def by_side(side: str) -> tuple[Choice, ...]:
    return tuple(c for c in CHOICES if c.side == side)


def render_markdown() -> str:
    """docs/LEGAL-CHOICES.md: the table, one section per side."""
    out = [
        "# The legal-choice space",
        "",
        "<!-- generated by `python -m conformance.protocol.legal > docs/LEGAL-CHOICES.md`; a test keeps it in step -->",
        "",
        "Every point where [PROTOCOL.md](PROTOCOL.md) lets an implementation choose: each MAY, each",
        "**[decision]**, each \"either … or\", and the freedoms on the wire it leaves open. The table is data",
        "(`conformance/protocol/legal.py`). *tester* says how a tester meets the point: **set** means it",
        "accepts every alternative and fails none; **flag** means a profile flag tells it which one the box",
        "took (the flag is given for each alternative that needs one). The first alternative is the default",
        "of `tests/impls`. *knob* is the setting of the independent implementations in",
        "`tests/impls` (`python -m tests.impls.box random --seed N`, `python -m tests.impls.matrix --sample N`)",
        "that takes exactly these alternatives; a test fails when a row has an alternative that is no knob",
        "value. A row without a knob is a decision a flag tells the tester (the independent implementations",
        "read it one way). Decisions with a single reading are no choice and not listed: the CRC's coverage and",
        "one frame per datagram (F7), poses answered 0000 with or without a cycle (S3), the readings D1–D6;",
        "nor are SHOULDs (a box that breaks one is NON-STRICT, not another legal choice).",
        "",
    ]
    for side, title in (("box", "The box (server)"), ("robot", "The robot (client)")):
        out += [f"## {title}", "", "| id | clauses | kind | choice | alternatives | tester | knob | note |",
                "|---|---|---|---|---|---|---|---|"]
        for c in by_side(side):
            alts = " · ".join(f"`{a}`" + (f" ({c.flags[a]})" if a in c.flags else "") for a in c.alternatives)
            knob = f"`{c.knob}`" if c.knob else "-"
            out.append(f"| {c.id} | {', '.join(c.clauses)} | {c.kind} | {c.question} | {alts} | {c.tester} | "
                       f"{knob} | {c.note} |")
        out.append("")
    out += _DIFFERENCES
    return "\n".join(out) + "\n"


_DIFFERENCES = [
    "## Readings the rows rest on",
    "",
    "- S1 lets a robot prime several parts in one session: CycleOn → CycleOff pairs may repeat between",
    "  stream on and stream off, each CycleOn closed by its CycleOff before the next (docs/PROTOCOL.md, the",
    "  robot side and \"What a tester must accept\"). That is *robot-cycles* above; certify-robot's S1 accepts it.",
    "- R6 (a) lets a receiver trust only a header whose start word **and version** are right: a header",
    "  with another version is rejected (resume) or closes the connection, never trusted. The transfer",
    "  type, the action and the block shape may each be trusted or rejected independently.",
    "- A5 names three reactions to a frame that is not a request (silence, a non-zero error, a close);",
    "  it does not say which action byte a refusal carries: both the echoed action and `00` are read as",
    "  legal (*refusal-action*).",
]


if __name__ == "__main__":
    print(render_markdown(), end="")
