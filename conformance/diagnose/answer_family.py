"""Answers built wrongly: the live experiments behind :mod:`.answer_shape` (each on a fresh connection).

* :func:`shapes` — each valid request's first answer (the ``alone`` experiment's, and ProgIdx/result request
  alone when a root cause asked for them) compared field by field with the allowed answers: the one field
  that differs, for the actions it differs on;
* :func:`byte_order` — a parse error of each block action alone (its action's named error is 1001/1002) and
  the valid requests' codes: the error code written little-endian, confirmed when swapping its two bytes makes
  every answer legal (and two different codes show it), else ruled out with the answer that contradicts it.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence

from ..harness.target import Unreachable
from ..i18n import gettext
from ..model.verdicts import CaseResult, RootCause
from ..protocol import ACTION_ERROR, Action, Transport, ValueBlock, peek_header, request
from ..protocol.constants import CHECK_LEN, HEADER_LEN, START_WORD
from .answer_shape import (
    Observed,
    ShapeDiff,
    grouped,
    shape_diff,
    shape_title,
    swap_hints,
    swap_story,
    swap_title,
    swapped,
)
from .experiments import BLOCK_ACTIONS, Prober, block_request
from .families import CYCLES, Found, _mech
from .hypotheses import LEGAL_CODES, Expect, Experiment, Mechanism, Status

PROG_IDX, RESULT = int(Action.PROG_IDX), int(Action.VISION_RESULT)
#: the program index a ProgIdx probe sends
PROBE_INDEX = 3


def extension_request(p: Prober, action: int) -> bytes:
    """A valid ProgIdx (one type-03 block) or result request, in the run's profile."""
    blocks = [ValueBlock(p.profile.first_index, PROBE_INDEX)] if action == PROG_IDX else []
    return p.codec.encode(request(Action(action), blocks), Transport.TCP)


def _first_answers(p: Prober, alone: Experiment | None, asked: Iterable[int],
                   exp: Experiment) -> list[tuple[int, bytes, bytes, int | None]]:
    """(action, request, first answer's bytes, its error) for every valid request answered alone."""
    out = []
    for ex in alone.exchanges if alone is not None else []:
        reading = ex.reading(0)
        if ex.frames and reading.answers and len(ex.frames[0]) > 5:
            out.append((ex.frames[0][5], ex.frames[0], reading.answers[0].raw, reading.answers[0].error))
    for action in (a for a in (PROG_IDX, RESULT) if a in set(asked)):
        frame = extension_request(p, action)
        got = p.exchange([frame], quiet=[True], settle=False)  # a short wait: a 27 may legally take its time (E5)
        if got is None or not got.reached:
            break
        exp.exchanges.append(got)
        if got.reading(0).answers:
            first = got.reading(0).answers[0]
            out.append((action, frame, first.raw, first.error))
    return out


def shapes(p: Prober, alone: Experiment | None, asked: Iterable[int]) -> Found:
    found = Found(Experiment("answer-fields", "each valid request alone: its answer compared field by field with "
                                              "the answers PROTOCOL.md allows (A2, E2, E3)"))
    answered = _first_answers(p, alone, asked, found.experiment)
    diffs: list[ShapeDiff] = []
    requests: dict[int, bytes] = {}
    for action, frame, raw, _error in answered:
        d = shape_diff(action, frame, raw, p.profile.byte_order)
        if d is not None:
            diffs.append(d)
            requests[action] = frame
    for group in grouped(diffs):
        first = group[0]
        found.mechanisms.append(_shape_mech(found, group, [(requests[first.action], Expect("valid", first.action))]))
    found.stories["answer-shape"] = ((Status.CONFIRMED, "") if found.mechanisms else
                                     (Status.RULED_OUT, f"{len(answered)} answers alone have the allowed fields")
                                     if answered else (Status.UNTESTED, "no answer to compare"))
    found.experiment.finding = "; ".join(m.title for m in found.mechanisms) or (
        f"{len(answered)} answers: every block field as allowed")
    return found


def _shape_mech(found: Found, group: list[ShapeDiff], repro: list[tuple[bytes, Expect]]) -> Mechanism:
    first = group[0]
    clause = {"echo-blocks": "A2", "blocks-attached": "A2", "transfer-type": "F3", "version": "F2"}.get(
        first.field, "E2" if first.action == PROG_IDX else "E3")
    return _mech("answer-shape", {d.action for d in group}, found, (clause,), repro, title=shape_title(group),
                 field=first.field, got=first.got, want=first.want)


def quoted_answers(causes: Sequence[RootCause], cases: Sequence[CaseResult]) -> list[bytes]:
    """The answer bytes the root causes' cases quote."""
    ids = {c for cause in causes for c in cause.cases}
    out = []
    for case in cases:
        if case.id in ids and case.received_hex:
            try:
                out.append(bytes.fromhex(case.received_hex.partition("…")[0]))
            except ValueError:
                continue
    return out


def byte_order(p: Prober, alone: Experiment | None, causes: Sequence[RootCause] = (),
               cases: Sequence[CaseResult] = ()) -> Found:
    """Run only when a code no action allows, swapped, is one A3 names (in the cases' answers or alone)."""
    found = Found(Experiment("error-byte-order", "a parse error of each block action alone (A3 names 1001/1002) "
                                                 "and each valid request's code: legal as sent, or legal with the "
                                                 "error code's two bytes swapped?"))
    alone_raw = [ex.reading(0).answers[0].raw for ex in (alone.exchanges if alone else []) if ex.reading(0).answers]
    if not swap_hints([*quoted_answers(causes, cases), *alone_raw], p.profile.byte_order):
        found.stories["error-byte-order"] = (Status.RULED_OUT, "no answer carries a code that is a named code swapped")
        return found
    seen: list[Observed] = []
    for _action, _frame, _raw, error in _first_answers(p, alone, (), found.experiment):
        legal = frozenset(LEGAL_CODES.get(_action, ()))
        if error is None or not legal:
            continue
        if _action in CYCLES and error not in legal and swapped(error) not in legal:
            continue  # S3: CycleOff while idle (CycleOn twice) MAY be answered with any error
        seen.append(Observed(_action, error, legal))
    bad_index = (p.profile.first_index + 1) & 0xFF
    repro: list[tuple[bytes, Expect]] = []
    for action in BLOCK_ACTIONS:
        frame = block_request(p, action, 1, 0, bad_index)
        ex = p.exchange([frame], quiet=[True], settle=False)
        if ex is None or not ex.reached:
            break
        found.experiment.exchanges.append(ex)
        heard = [a for a in ex.reading(0).answers if a.action == action and a.error is not None]
        if heard and heard[0].error is not None:
            named = int(ACTION_ERROR[Action(action)])
            seen.append(Observed(action, heard[0].error, frozenset({named})))
            repro = repro or [(frame, Expect("valid", action, (named,)))]
    confirmed, why = swap_story(seen)
    if confirmed and repro:
        wrong = {o.action for o in seen if o.code not in o.legal}
        found.mechanisms.append(_mech("error-byte-order", wrong, found, ("F4", "A3"), repro, title=swap_title(seen, p.profile.byte_order)))
    found.stories["error-byte-order"] = (Status.CONFIRMED, why) if found.mechanisms else (
        (Status.RULED_OUT, why) if seen else (Status.UNTESTED, "no error code heard"))
    found.experiment.finding = why
    return found


#: how long the bytes after a lone request's answer are read for
TRAILING_SETTLE_S = 0.3


def trailing(p: Prober, asked: Iterable[int]) -> Found:
    """A lone NONE on a fresh connection, every byte read for a moment after its answer: one frame and nothing
    else, or one frame followed by bytes that are not a frame (a buffer sized past the frame)? A box that writes
    one stray byte after each answer looks, to a reader, like a box answering twice."""
    found = Found(Experiment("answer-bytes", "a lone NONE on a fresh connection: exactly one frame's bytes back, or "
                                             "the frame followed by bytes that are not a frame?"))
    if int(Action.NONE) not in set(asked) or p.left() < p.dialer.wait_s() + 1.0:
        return found
    none = p.valid_request(int(Action.NONE))
    try:
        conn = p.dialer.dial("diagnose: the bytes of one answer")
    except Unreachable:
        return found
    p.count += 1
    try:
        conn.send(none, "diagnose: a lone NONE")
        conn.receive(p.dialer.by())
        conn.receive(time.monotonic() + TRAILING_SETTLE_S)  # whatever follows the answer
        raw = p.dialer.transcript.received(conn.conn_id)
    finally:
        conn.close("diagnose: the bytes of one answer")
    extra = trailing_bytes(raw, p.profile.byte_order)
    found.experiment.finding = f"{len(raw)} bytes back: {raw.hex(' ')}"
    if extra:
        found.mechanisms.append(_mech("answer-shape", {int(Action.NONE)}, found, ("F5", "A2"),
                                      [(none, Expect("valid", int(Action.NONE)))], title=trailing_title(raw, extra),
                                      field="trailing"))
    return found


def trailing_bytes(raw: bytes, byte_order: str) -> bytes:
    """The bytes after the first answer frame in ``raw`` when they are fewer than a header and hold no start word
    (b"" when ``raw`` is one frame exactly, or more frames follow)."""
    head = peek_header(raw, 0, byte_order)
    if head is None or head.start_word != START_WORD:
        return b""
    end = HEADER_LEN + head.block_count * head.block_length + CHECK_LEN
    rest = raw[end:]
    return rest if 0 < len(rest) < HEADER_LEN and START_WORD.to_bytes(2, "big") not in rest else b""


def trailing_title(raw: bytes, extra: bytes) -> str:
    return gettext("Writes {n} extra byte(s) ({hex}) after each answer's check field ({size} bytes for a {frame}-byte "
                   "frame): the next answer then seems to start with a stray byte, as if the box answered twice; "
                   "F5/A2 ask for exactly 12+N×L+2 bytes per answer — size the answer buffer to the frame").format(
        n=len(extra), hex=extra.hex(" "), size=len(raw), frame=len(raw) - len(extra))
