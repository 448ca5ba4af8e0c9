"""What the suite should conclude about each independent implementation, as data.

A conforming implementation must come out clean: exit 0, no FAIL, ERROR or
NON-STRICT. A broken one must be caught, and the *first* root cause the suite
reports (``summary.json["root_causes"][0]``) must name one of ``clauses`` at
``level`` (FAIL for a MUST, NON-STRICT for a SHOULD). ``clauses[0]`` is the clause the
defect was planted to break; the others are acceptable names for the same defect.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Expectation:
    name: str
    role: str  # "box" (judged by ``run``) or "robot" (judged by ``certify-robot``)
    conforming: bool
    clauses: tuple[str, ...] = ()
    level: str = ""  # "FAIL" or "NON-STRICT" for a broken one
    suite_args: tuple[str, ...] = ()  # extra suite flags this implementation needs
    note: str = ""

    @property
    def clean(self) -> bool:
        return self.conforming


def _ok(name: str, role: str = "box", *suite_args: str, note: str = "") -> Expectation:
    return Expectation(name, role, True, suite_args=suite_args, note=note)


def _bad(name: str, clauses: tuple[str, ...], level: str = "FAIL", role: str = "box", note: str = "") -> Expectation:
    return Expectation(name, role, False, clauses, level, note=note)


EXPECTATIONS: dict[str, Expectation] = {e.name: e for e in [
    # boxes, conforming: each a different legal reading
    _ok("resync-fine"),
    _ok("skip-header"),
    _ok("trust-header", note="serves UDP too: the matrix passes --udp-target"),
    _ok("close-on-garbage"),
    _ok("byte-by-byte"),
    _ok("strict-cycle"),
    _ok("strict-cycle-box"),
    _ok("unknown-error"),
    _ok("nan-1001", note="no extension E: the suite must detect it and skip E"),
    # boxes, broken: one planted defect each
    _bad("swapped-version", ("F2",)),
    _bad("swapped-error", ("A3", "F4"),
         note="1001 goes out as 01 10: the error field in the other byte order (F4), so not the A3 code"),
    _bad("wrong-transfer-type", ("F3",)),
    _bad("zero-to-malformed", ("A3", "R1")),
    _bad("one-at-a-time", ("S4",)),
    _bad("leaky", ("S5",)),
    _bad("dead", ("T1", "A1")),
    _bad("slow-bytes", ("T1",)),
    _bad("late-cycle-on", ("T1", "S2")),
    _bad("flood-random", ("R5", "F1", "A1"),
         note="the bytes break F1/A1; the point is that the suite stays bounded in time and memory (R5)"),
    _bad("flood-headers", ("R5", "F5", "A2"),
         note="answers announcing 255x65535 block bytes that never end; the suite must stay bounded (R5)"),
    _bad("no-resync", ("R6",), "NON-STRICT"),
    _bad("nan-zero", ("B4",), "NON-STRICT"),
    _bad("drops-coalesced", ("R4", "A1")),
    _ok("late-inside-timeout", note="every answer 100 ms late: legal (T1), and slow for every sequential wait"),
    _bad("sticky-error", ("A4", "A1", "A3", "S1", "S2", "S3", "R1")),
    _bad("drops-frames", ("A1", "T1", "S6")),
    _bad("answers-some-actions", ("A1", "T1")),
    _bad("quiet-after-n", ("T1", "A1", "R2")),
    _bad("short-send-drops", ("S6", "A1", "F5")),
    _bad("latency-grows", ("T2", "S6", "T1", "A1", "S4")),
    _bad("drops-unsendable", ("S6", "A1", "F5"),
         note="its send buffer is the kernel's default: only a window closed at Ethernet sizes fills it"),
    _bad("low-byte-length", ("F4", "F5", "B1", "R1"),
         note="L = 0x0119 passes as 25: only F4-02, which changes each byte of each field on its own, sees it"),

    # issue 36: the kinds of box written outside this project that took longest
    _bad("drops-rest-of-read", ("R4", "A1", "T1", "R3", "S6")),
    _bad("split-header-lost", ("R3", "A1", "T1", "R6")),
    _ok("slow-pieces", note="every answer 20 ms late, in two pieces with Nagle on: legal (T1)"),
    _ok("slow-cycle-on", note="CycleOn answered after 0.6 time_out: legal (T1)"),

    _ok("completes-short", note="a short bad header takes the next request's first bytes: a second probe is answered"),
    _bad("stall-once", ("T1", "S4"), note="a box-wide stall, never an R6 of the input in flight"),
    _bad("udp-crc-ccitt", ("F7",)),
    _bad("udp-no-crc-check", ("R7", "F7")),
    _bad("udp-crc-header", ("F7",)),
    _bad("udp-answer-port", ("F7", "A1")),
    _bad("udp-two-frames", ("F7", "R7")),
    _bad("tcp-check-crc", ("F6",)),
    _bad("tcp-crc-refused", ("F6",), "NON-STRICT"),
    # robots, conforming
    _ok("canonical", "robot"),
    _ok("karel-calls", "robot", note="poses (23/24) on the command connection are legal: PROTOCOL.md, robot side"),
    _ok("extension", "robot", note="E4 needs no flag: certify-robot judges the session the robot runs (ProgIdx)"),
    # robots, broken
    _bad("transfer-10", ("F3",), role="robot"),
    _bad("index-1", ("B3",), role="robot"),
    _bad("cycle-on-first", ("S1",), role="robot"),
    _bad("nan-pose", ("B4",), "NON-STRICT", role="robot"),
    _bad("slow-stream", ("T2",), role="robot"),
    Expectation("stream-45hz", "robot", False, ("T2",), "FAIL", suite_args=("--rate-tolerance", "5"),
                note="45 Hz declared 50: the default 10 % tolerance is exactly its rate, so judged at 5 %"),
    _bad("stream-open", ("S5",), role="robot"),
    _bad("little-floats", ("F4",), role="robot"),
    _bad("no-wait", ("A1",), role="robot", note="found only against a box that takes time to answer (certify-robot's "
         "--answer-latency, on by default)"),
]}


#: The name of a random legal combination (``--sample``): conforming by construction.
RANDOM = "random"


def expectation(name: str, role: str = "box") -> Expectation:
    """The expectation for ``name``; every random legal combination must come out clean."""
    if name != RANDOM:
        return EXPECTATIONS[name]
    # T2's jitter on a loaded machine is the scheduling of a Python robot, no legal choice: judged loosely
    return _ok(RANDOM, role, *(("--jitter-tolerance", "600", "--rate-tolerance", "25") if role == "robot" else ()))


def judge(expectation: Expectation, exit_code: int | None, totals: dict[str, int],
          root_causes: list[dict[str, object]] | None, first_clauses: tuple[str, ...] = ()) -> str:
    """Compare one suite run with its expectation: "ok", or what went wrong.

    ``first_clauses``: the clauses of the first FAIL/NON-STRICT case, used when the
    suite wrote no ``root_causes`` (then the verdict ends in "?": a weaker check).
    """
    bad = totals.get("FAIL", 0) + totals.get("ERROR", 0)
    strict = totals.get("NON-STRICT", 0)
    if exit_code is None:
        return "NO RESULT (suite killed or did not start)"
    if expectation.conforming:
        if exit_code == 0 and bad == 0 and strict == 0:
            return "ok"
        return f"FALSE ALARM ({bad} FAIL/ERROR, {strict} NON-STRICT, exit {exit_code})"
    if bad == 0 and strict == 0:
        return "MISSED (clean verdict)"
    if root_causes:
        first = root_causes[0]
        named = tuple(str(c) for c in first.get("clauses", ()))  # type: ignore[attr-defined]
        level = {"MUST": "FAIL", "SHOULD": "NON-STRICT"}.get(str(first.get("level", "")), str(first.get("level", "")))
        if not set(named) & set(expectation.clauses):
            return f"WRONG CLAUSE (first root cause names {','.join(named) or '-'})"
        if level and level != expectation.level:
            return f"WRONG LEVEL ({level}, expected {expectation.level})"
        return "ok"
    if expectation.level == "FAIL" and bad == 0:
        return "WRONG LEVEL? (only NON-STRICT, expected FAIL)"
    if expectation.level == "NON-STRICT" and bad:
        return f"WRONG LEVEL? ({bad} FAIL/ERROR, expected only NON-STRICT)"
    if set(first_clauses) & set(expectation.clauses):
        return "ok?"
    return f"WRONG CLAUSE? (first failing case names {','.join(first_clauses) or '-'})"
