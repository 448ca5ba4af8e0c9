"""Isolation's dimensions beyond the bytes of one request (see :mod:`.isolate`), each a live experiment that
pins one difference and returns it as an :class:`~.differences.Isolated` (None: it did not show):

* :func:`answer_check` — what an answer's check field holds over TCP: a CRC of the profile set, in which byte order;
* :func:`split` — a frame whole vs split (inside its header, after it, byte by byte): R3;
* :func:`float_value` — a float value isolated: its class, the threshold between the passing and failing value
  (bisection), and the byte order the box reads it in;
* :func:`unanswered` — a valid request left unanswered alone while a NONE behind it is answered;
* :func:`connection_held` — a request mishandled on the connection that holds the cycle, answered on another;
* :func:`latency_growth` — the answer latency against the number of requests on a connection, and on a fresh one;
* :func:`refine_cycle` — a family's "pose refused in a cycle" put to :func:`connection_held`.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import replace

import crcmod.predefined

from ..protocol.constants import HEADER_LEN
from ..protocol.profile import crc16_names
from . import isolation_titles as T
from .differences import REQUESTS, Isolated
from .experiments import Prober
from .hypotheses import Experiment, Mechanism
from .probes import GAP_S, beside, full_wait, in_pieces, latencies

#: the CRC-16 algorithms tried first (the profile set), as titles name them
CRC_TITLES = {"modbus": "CRC-16/MODBUS", "crc-16": "CRC-16/ARC", "crc-ccitt-false": "CRC-16/CCITT-FALSE",
              "xmodem": "CRC-16/XMODEM", "kermit": "CRC-16/KERMIT", "x-25": "CRC-16/X-25", "crc-16-usb": "CRC-16/USB",
              "crc-16-maxim": "CRC-16/MAXIM"}
#: requests per connection, and the growth (ms) that counts as a latency that grows
LATENCY_REQUESTS = 180
LATENCY_GROWTH_MS = 20.0
#: bisection steps between a passing and a failing float value
FLOAT_STEPS = 40
#: the gap between a split frame's pieces that a box with an inter-byte timeout may not wait for
SLOW_GAP_S = 0.6


def crc_of(body: bytes, check: bytes) -> tuple[str, str] | None:
    """(algorithm, byte order) of a CRC-16 over ``body`` equal to ``check`` (the profile set first)."""
    names = [n for n in CRC_TITLES if n in crc16_names()] + [n for n in crc16_names() if n not in CRC_TITLES]
    for name in names:
        value = crcmod.predefined.mkPredefinedCrcFun(name)(body)
        for order in ("big", "little"):
            if value.to_bytes(2, order) == check:
                return CRC_TITLES.get(name, name.upper()), order
    return None


def answer_check(p: Prober, exp: Experiment) -> Isolated | None:
    """A NONE on a fresh connection: what its answer's check field holds, when not 00 00."""
    ex = p.exchange([p.valid_request(0)], settle=False)
    if ex is None or not ex.reached:
        return None
    exp.exchanges.append(ex)
    answers = ex.reading(0).answers
    if not answers or len(answers[0].raw) < HEADER_LEN + 2 or answers[0].raw[-2:] == b"\x00\x00":
        return None
    raw = answers[0].raw
    named = crc_of(raw[:-2], raw[-2:])
    title = T.answer_crc(named[0], named[1], raw[-2:].hex(" ")) if named else T.answer_check(raw[-2:].hex(" "))
    return Isolated(("answer-check", named), title, ("F6",), 0, (p.valid_request(0),), {"check": raw[-2:].hex(),
                                                                                      "crc": named})


def split(p: Prober, exp: Experiment, frame: bytes) -> Isolated | None:
    """A frame answered right whole: split inside its header, right after it, then byte by byte."""
    cuts = {"inside": [5], "after": [HEADER_LEN]}
    seen: dict[str, bool] = {}
    for where, at in cuts.items():
        if len(frame) <= at[0]:
            continue
        reading = in_pieces(p, exp, frame, at)
        if reading is None:
            return None
        seen[where] = not _answered(frame, reading.answers)
    if not any(seen.values()):
        reading = in_pieces(p, exp, frame, list(range(1, len(frame))))
        if reading is None:
            return None
        if not _answered(frame, reading.answers):
            return Isolated(("split", "bytes"), T.split_bytes(), ("R3",), frame[5], (frame,), {"cut": "every byte"})
        slow = in_pieces(p, exp, frame, [HEADER_LEN], SLOW_GAP_S)  # the same cut, the pieces further apart
        if slow is None or _answered(frame, slow.answers):
            return None
        return Isolated(("split", "slow"), T.split_slow(int(SLOW_GAP_S * 1000), int(GAP_S * 1000)), ("R3", "T1"),
                        frame[5], (frame,), {"gap_ms": int(SLOW_GAP_S * 1000)})
    if seen.get("inside") and not seen.get("after"):
        return Isolated(("split", "header"), T.split_header(), ("R3",), frame[5], (frame,), {"cut": 5})
    return Isolated(("split", "frame"), T.split_any(), ("R3",), frame[5], (frame,), {"cut": sorted(seen)})


def _answered(frame: bytes, answers: tuple[object, ...]) -> bool:
    return any(getattr(a, "action", None) == frame[5] for a in answers)


def as_float(raw: bytes, order: str) -> float:
    return float(struct.unpack(">f" if order == "big" else "<f", raw)[0])


def _pack(value: float, order: str) -> bytes:
    return struct.pack(">f" if order == "big" else "<f", value)


def float_value(p: Prober, passing: bytes, failing: bytes, at: int,
                judge: Callable[[bytes], bool | None]) -> tuple[str, str] | None:
    """The value at ``at`` isolated: ("byte-order", words) when the box reads it the other way round, ("threshold",
    words) when a bound lies between the passing and failing values, else None. ``judge(frame)``: the live
    judge (True: the box answers the frame 0000)."""
    order = p.profile.float_byte_order
    finite, infinite = b"\x00\x00\x80\x7f", b"\x7f\x80\x00\x00"  # tiny finite / +inf in big-endian, the other way little
    if order == "little":
        finite, infinite = infinite, finite
    tries = []
    for value in (finite, infinite):
        probe = bytearray(passing)
        probe[at:at + 4] = value
        tries.append(judge(bytes(probe)))
    if tries == [False, True]:  # the finite value refused, the infinite one answered 0000: read the other way round
        return "byte-order", "little" if order == "big" else "big"
    good, bad = as_float(passing[at:at + 4], order), as_float(failing[at:at + 4], order)
    if not (math.isfinite(good) and math.isfinite(bad)) or good == bad:
        return None
    for _ in range(FLOAT_STEPS):
        geometric = good * bad > 0 and max(abs(good), abs(bad)) > 4 * min(abs(good), abs(bad))
        mid = math.copysign(math.sqrt(good * bad), good) if geometric else (good + bad) / 2
        probe = bytearray(passing)
        probe[at:at + 4] = _pack(mid, order)
        verdict = judge(bytes(probe))
        if verdict is None:
            return None
        good, bad = (mid, bad) if verdict else (good, mid)
        if abs(bad - good) <= 1e-4 * max(1.0, abs(good)):
            break
    return "threshold", f"{_round(good, bad):g}"


def _round(good: float, bad: float) -> float:
    """The roundest number between the last passing and the first failing value (a bound a firmware writes)."""
    lo, hi = min(good, bad), max(good, bad)
    for digits in range(-3, 7):
        step = 10.0 ** -digits
        candidate = math.ceil(lo / step) * step
        if candidate <= hi:
            return round(candidate, max(digits, 0))
    return good


def unanswered(p: Prober, exp: Experiment, frame: bytes) -> Isolated | None:
    """A valid request alone, a NONE behind it: the request unanswered while the NONE is answered."""
    if not full_wait(p, 2):
        return None
    ex = p.exchange([frame, p.valid_request(0)], settle=True)  # a late answer to the request is read too
    if ex is None or not ex.reached:
        return None
    exp.exchanges.append(ex)
    first, after = ex.reading(0), ex.reading(1)
    late = any(a.action == frame[5] for a in after.answers)  # answered after time_out: late (T1), not never
    if first.answers or first.closed or late or not any(a.action == 0 for a in after.answers):
        return None
    return Isolated(("no-answer", frame[5]), T.no_answer(frame[5]), ("A1", "T1"), frame[5], (frame,), {})


def connection_held(p: Prober, exp: Experiment, frame: bytes) -> Isolated | None:
    """CycleOn on connection A, then ``frame`` on B and on A: refused on A only (the command connection)."""
    on = p.valid_request(0x01)
    got = beside(p, exp, [on], frame)
    if got is None:
        return None
    other, same = got
    ok_other = any(a.action == frame[5] and a.error == 0 for a in other.answers)
    ok_same = any(a.action == frame[5] and a.error == 0 for a in same.answers)
    p.exchange([p.valid_request(0x02)], settle=False)  # leave the cycle off (S3: idle first)
    if not ok_other or ok_same:
        return None
    what = T.done_to(same.answers[0].error or 0 if same.answers else None, same.closed)
    return Isolated(("cycle-connection", frame[5]), T.cycle_connection(frame[5], what), ("S3", "S1"), frame[5],
                    (on, frame), {"what": what})


def latency_growth(p: Prober, exp: Experiment) -> Isolated | None:
    """NONE requests one after the other on one connection: does the latency grow with their number, and does a
    fresh connection start fast again?"""
    times = latencies(p, exp, p.valid_request(0), LATENCY_REQUESTS)
    if len(times) < 40:
        return None
    head = sorted(times[:20])[10]
    tail = sorted(times[-20:])[10]
    exp.finding = f"{len(times)} NONE on one connection: median {head:.1f} ms over the first 20, {tail:.1f} ms over the last 20"
    if tail - head < LATENCY_GROWTH_MS:
        return None
    start = next((i for i, t in enumerate(times) if t - head >= LATENCY_GROWTH_MS / 2), len(times))
    fresh = latencies(p, exp, p.valid_request(0), 5)
    per_connection = bool(fresh) and sorted(fresh)[len(fresh) // 2] - head < LATENCY_GROWTH_MS / 2
    knee = max(1, _knee(times, head))
    return Isolated(("latency-grows", per_connection), T.latency_grows(knee, head, tail, len(times), per_connection),
                    ("T2", "T1"), 0, (p.valid_request(0),), {"first_ms": round(head, 1), "last_ms": round(tail, 1),
                                                          "requests": len(times), "from": knee, "slow_from": start})


def _knee(times: list[float], base: float) -> int:
    """The request count from which the latency rises steadily (a straight line fitted to the tail, back to base)."""
    n = len(times)
    tail = times[n // 2:]
    xs = list(range(n // 2, n))
    mx, my = sum(xs) / len(xs), sum(tail) / len(tail)
    var = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, tail)) / var if var else 0.0
    if slope <= 0:
        return 0
    return int(round(mx - (my - base) / slope)) + 1


def block_len(frame: bytes) -> int:
    return REQUESTS.get(frame[5], (0, 0))[0]


def refine_cycle(p: Prober, mechanisms: list[Mechanism]) -> None:
    """A pose refused while a cycle is on (the cycle family), put to the connection dimension: refused on the
    connection that sent CycleOn only (the command connection), or on every connection? (in place)"""
    for i, m in enumerate(mechanisms):
        if m.kind != "cycle-dependent" or not m.detail.get("inside") or p.left() < 1.0:
            continue
        exp = Experiment("cycle-connection", "CycleOn on one connection; the same pose on a second connection, "
                                             "then on the first")
        held = connection_held(p, exp, p.valid_request(0x23))
        if held is not None:
            mechanisms[i] = replace(m, title=held.title, clauses=held.clauses,
                                    detail={**m.detail, "connection": "the one that sent CycleOn"})


def refine_refused(p: Prober, mechanisms: list[Mechanism]) -> None:
    """Every valid block request of an action refused or unanswered (the answers family), put to the byte order of the block
    length: the same request with its two bytes swapped answered 0000 means the box reads it little-endian."""
    for i, m in enumerate(mechanisms):
        action = next(iter(m.actions), None)
        if m.kind not in ("refuses-valid", "missing-answer") or action not in REQUESTS or not REQUESTS[action][0] \
                or p.left() < 1.0:
            continue
        exp = Experiment("block-length-order", "the refused request with its block length's two bytes swapped")
        frame = bytearray(p.valid_request(action))
        frame[8], frame[9] = frame[9], frame[8]
        ex = p.exchange([bytes(frame)], quiet=[True], settle=False)
        if ex is None or not ex.reached:
            return
        exp.exchanges.append(ex)
        if any(a.action == action and a.error == 0 for a in ex.reading(0).answers):
            title = T.length_order(action, bytes(frame[8:10]).hex(" "), m.kind == "refuses-valid")
            mechanisms[i] = replace(m, title=title, clauses=("F4", "B5"), detail={**m.detail, "order": "little"})
