"""The UDP family and the TCP check field: which reading of F6/F7/R7 the box has, told apart live.

The root causes :mod:`conformance.engine.transport_causes` gathers (``udp``: the F7/R7 cases and UDP
fuzz findings; ``tcp-check``: F6) are diagnosed here, apart from the TCP families, with datagrams
sent from an unconnected socket whose neighbouring ports listen too (:class:`~..harness.udp_probe.UdpProbe`):

* where the answers go: to the port the request came from, or another (and from which port);
* which CRC: the profile's; else every crcmod 16-bit algorithm in both byte orders (common ones
  first, a short wait each, a hit confirmed with a longer one), and whether the answers are
  signed with it too;
* whether the CRC is checked at all (a check no algorithm computes), both of its bytes, and what it covers (a pose
  datagram whose CRC covers the whole frame, the header only, the frame without its start word,
  the blocks only);
* one frame per datagram: two frames in one datagram, trailing bytes, and the answers' own length;
* TCP: the check field of an answer (F6: 00 00), and which CRC it is when it is one.

The first mechanism in :data:`ORDER` titles the root cause; the others are listed as its hypotheses.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from ..engine.transport_causes import TCP_CHECK, UDP
from ..harness.target import Target
from ..harness.udp_probe import Asked, UdpProbe
from ..model.verdicts import RootCause
from ..protocol import Action, Frame, PoseBlock, crc16_names, crc_function, encode_body, peek_header, request
from ..protocol.constants import CHECK_LEN, HEADER_LEN
from ..protocol.profile import ByteOrder
from . import titles, udp_titles
from .experiments import MIN_LEFT_S, POSE, Prober
from .hypotheses import Exchange, Experiment, Heard, Hypothesis, Mechanism, Reading, Status

#: the root-cause kinds this family diagnoses
KINDS = (UDP, TCP_CHECK)
#: mechanism kinds, the one that titles a root cause first
ORDER = ("udp-answer-port", "udp-answer-source", "udp-silent", "udp-crc-algorithm", "udp-crc-byte-order",
         "udp-crc-unchecked", "udp-crc-one-byte", "udp-crc-coverage", "udp-several-frames", "udp-trailing", "udp-short-completed", "udp-answer-frames",
         "udp-answer-crc", "tcp-check-field", "tcp-crc-refused")
TCP_KINDS = ("tcp-check-field", "tcp-crc-refused")
_CLAUSES = {"udp-answer-port": ("F7", "A1"), "udp-answer-source": ("F7", "A1"), "udp-silent": ("F7", "A1"),
            "udp-crc-unchecked": ("R7", "F7"), "udp-crc-one-byte": ("R7", "F7"), "udp-several-frames": ("F7", "R7"), "udp-trailing": ("F7", "R7"),
            "udp-short-completed": ("R7", "F7"),
            "tcp-check-field": ("F6",), "tcp-crc-refused": ("F6",)}
#: tried first when the profile's CRC is not answered (then every other crcmod 16-bit algorithm)
COMMON_CRCS = ("modbus", "crc-ccitt-false", "xmodem", "kermit", "x-25", "crc-16", "crc-16-usb", "crc-16-maxim")
SCAN_WAIT_S = 0.1
CONFIRM_WAIT_S = 1.0
#: the phase's share of time the family may take when TCP root causes wait too
SHARE = 0.6


@dataclass
class Lab:
    experiment: Experiment
    mechanisms: list[Mechanism] = field(default_factory=list)
    tried: list[str] = field(default_factory=list)  # what was asked, in words (the hypotheses ruled out)

    def found(self, kind: str, **detail: object) -> None:
        self.mechanisms.append(Mechanism(kind, frozenset(), self.experiment.name, udp_titles.of(kind, dict(detail)),
                                         _CLAUSES.get(kind, ("F7",)), (), dict(detail)))

    def has(self, *kinds: str) -> bool:
        return any(m.kind in kinds for m in self.mechanisms)


class _Datagrams:
    """Frames as datagrams under a CRC, byte order and coverage; and what came back, judged."""

    def __init__(self, p: Prober, u: UdpProbe, deadline: float) -> None:
        self.p, self.u, self.deadline = p, u, deadline
        self.profile = p.profile
        self.crc, self.order = p.profile.crc, p.profile.crc_byte_order

    def body(self, frame: Frame) -> bytes:
        return encode_body(frame, self.profile)

    def signed(self, body: bytes, crc: str | None = None, order: ByteOrder | None = None,
               cover: tuple[int, int] | None = None) -> bytes:
        first, last = cover if cover is not None else (0, len(body) - 1)
        value = crc_function(crc or self.crc)(body[first:last + 1])
        return body + value.to_bytes(2, order or self.order)

    def ask(self, lab: Lab, data: bytes, wait_s: float, note: str) -> Asked | None:
        left = min(self.deadline - time.monotonic(), self.p.left())
        if left < MIN_LEFT_S:
            return None
        asked = self.u.ask(data, min(wait_s, left), note=note)
        lab.experiment.exchanges.append(_exchange(asked, self.profile.byte_order))
        return asked

    def zeros(self, asked: Asked | None, action: int) -> int:
        """How many answers with ``action`` and 0000 came back (to any port)."""
        if asked is None:
            return 0
        count = 0
        for h in asked.heard:
            head = peek_header(h.data, 0, self.profile.byte_order)
            count += head is not None and head.action == action and head.error_code == 0
        return count


def _exchange(asked: Asked, byte_order: str) -> Exchange:
    heard = []
    for h in asked.heard:
        head = peek_header(h.data, 0, byte_order)
        where = "" if h.offset == 0 else f"reached port {'+' if h.offset > 0 else ''}{h.offset} of the sender"
        heard.append(Heard(head.action if head else None, head.error_code if head else None, h.data, where))
    return Exchange((asked.sent,), (Reading(tuple(heard)),))


def _pose(p: Prober) -> Frame:
    return request(Action.POSE, p.codec.pose_blocks([POSE]))


def crc_matches(body: bytes, check: bytes) -> list[tuple[str, ByteOrder]]:
    """Every (crcmod algorithm, byte order) whose CRC of ``body`` is ``check``."""
    return [(name, order) for name in crc16_names() for order in ("big", "little")
            if crc_function(name)(body).to_bytes(2, order) == check]


def candidates(profile_crc: str, profile_order: ByteOrder) -> list[tuple[str, ByteOrder]]:
    names = dict.fromkeys(n for n in (profile_crc, *COMMON_CRCS, *crc16_names()) if n in crc16_names())
    other: ByteOrder = "little" if profile_order == "big" else "big"
    pairs = [(name, order) for name in names for order in (profile_order, other)]
    return [pair for pair in pairs if pair != (profile_crc, profile_order)]


# -- the experiments ----------------------------------------------------------------------------------------
def where_answers_go(d: _Datagrams, lab: Lab, asked: Asked) -> None:
    """Answers heard elsewhere than at the sending port, or from another port than the box's."""
    if not asked.heard:
        return
    first = asked.heard[0]
    if first.offset != 0:
        lab.found("udp-answer-port", offset=first.offset, to=d.u.port + first.offset, source=d.u.port)
    elif first.source_port != d.u.target.port:
        lab.found("udp-answer-source", source=first.source_port, port=d.u.target.port)


def answer_shape(d: _Datagrams, lab: Lab, asked: Asked) -> None:
    """The answer datagram: one frame? signed with the profile's CRC?"""
    if not asked.heard:
        return
    raw = asked.heard[0].data
    head = peek_header(raw, 0, d.profile.byte_order)
    if head is None:
        return
    end = HEADER_LEN + head.block_count * head.block_length
    if len(raw) != end + CHECK_LEN:
        lab.found("udp-answer-frames", size=len(raw), frame=end + CHECK_LEN)
        return
    if raw[end:] != d.signed(raw[:end])[end:]:
        lab.found("udp-answer-crc", check=raw[end:].hex(" "), profile=d.crc, matches=crc_matches(raw[:end], raw[end:]))


def scan_crc(d: _Datagrams, lab: Lab, body: bytes) -> tuple[str, ByteOrder] | None:
    """The (algorithm, byte order) under which a NONE datagram is answered 0000 (confirmed), or None."""
    previous: tuple[str, ByteOrder] | None = None
    seen: set[bytes] = {d.signed(body)[-2:]}
    tried = 0
    for pair in candidates(d.crc, d.order):
        data = d.signed(body, *pair)
        if data[-2:] in seen:
            continue
        seen.add(data[-2:])
        tried += 1
        asked = d.ask(lab, data, SCAN_WAIT_S, f"NONE datagram, CRC {pair[0]} {pair[1]}-endian")
        if asked is None:
            return None
        if d.zeros(asked, Action.NONE):
            for cand in [pair, *([previous] if previous else [])]:  # a slow answer may be the previous try's
                again = d.ask(lab, d.signed(body, *cand), CONFIRM_WAIT_S, f"confirm: CRC {cand[0]} {cand[1]}-endian")
                if d.zeros(again, Action.NONE):
                    lab.tried.append(f"{tried} CRC/byte-order combinations tried before {cand[0]} {cand[1]}-endian")
                    return cand
        previous = pair
    lab.tried.append(f"{tried + 1} CRC/byte-order combinations tried, none answered")
    lab.experiment.finding = f"no NONE datagram answered under {tried + 1} CRC/byte-order combinations"
    return None


def _no_crc_value(body: bytes) -> bytes:
    taken = {crc_function(n)(body).to_bytes(2, o) for n in crc16_names() for o in ("big", "little")}
    value = 0x5AA5
    while value.to_bytes(2, "big") in taken:
        value = (value + 0x0101) & 0xFFFF
    return value.to_bytes(2, "big")


def coverage(d: _Datagrams, lab: Lab, wait_s: float) -> None:
    """A pose datagram under the working CRC; refused, then under CRCs over parts of it."""
    body = d.body(_pose(d.p))
    asked = d.ask(lab, d.signed(body), wait_s, "pose datagram, CRC over the whole frame")
    if asked is None or d.zeros(asked, Action.POSE):
        return
    last = len(body) - 1
    for cover in ((0, HEADER_LEN - 1), (2, last), (HEADER_LEN, last), (2, HEADER_LEN - 1)):
        asked = d.ask(lab, d.signed(body, cover=cover), SCAN_WAIT_S * 3, f"pose datagram, CRC over bytes {cover}")
        if asked is None:
            return
        if d.zeros(asked, Action.POSE):
            lab.found("udp-crc-coverage", cover=cover)
            return
    lab.tried.append("a pose datagram refused under CRCs over the whole frame and four parts of it")


def one_byte(d: _Datagrams, lab: Lab, body: bytes) -> None:
    """The CRC with one of its two bytes changed (each on its own, a short wait each): answered 0000 when the box
    compares the other byte only (the one answered asked again with a longer wait, so that a slow answer to the
    first is not taken for an answer to the second)."""
    good = d.signed(body)
    changed = [body + bytes([good[-2] ^ 0xFF, good[-1]]), body + bytes([good[-2], good[-1] ^ 0xFF])]
    passed = [bool(d.zeros(d.ask(lab, data, SCAN_WAIT_S * 3, f"NONE datagram, byte {at + 1} of the CRC changed"),
                           Action.NONE)) for at, data in enumerate(changed)]
    if passed.count(True) != 1:
        return
    ignored = passed.index(True)
    again = d.ask(lab, changed[ignored], CONFIRM_WAIT_S, f"confirm: byte {ignored + 1} of the CRC changed")
    if d.zeros(again, Action.NONE):
        lab.found("udp-crc-one-byte", ignored=ignored + 1, checked=2 - ignored, at=len(body) + ignored)


def datagram_length(d: _Datagrams, lab: Lab, wait_s: float) -> None:
    """Two frames in one datagram, and a frame with trailing bytes: answered 0000?"""
    pose = d.signed(d.body(_pose(d.p)))
    register = d.signed(d.body(request(Action.REGISTER_POSE, [PoseBlock(d.p.profile.first_index, POSE)])))
    asked = d.ask(lab, pose + register, wait_s, "a pose and a register pose in one datagram")
    n = d.zeros(asked, Action.POSE) + d.zeros(asked, Action.REGISTER_POSE)
    if n:
        lab.found("udp-several-frames", n=n)
        return
    asked = d.ask(lab, pose + b"\0\0", wait_s, "a pose datagram with two bytes after its frame")
    if d.zeros(asked, Action.POSE):
        lab.found("udp-trailing", n=2)


#: a second pose, unlike :data:`~.experiments.POSE` in every value: the datagram sent before a short copy of the first
OTHER_POSE = (-1.5, 2.5, -3.5, 4.5, -5.5, 6.5)
#: bytes taken off the end of a pose datagram: its last block byte and its CRC
SHORT_BY = 3


def short_after_whole(d: _Datagrams, lab: Lab, wait_s: float) -> None:
    """A pose datagram short of its last bytes, answered 0000 right after the same datagram whole, and dropped after
    another one: the box completes a short datagram with what the previous one left in its buffer."""
    whole = d.signed(d.body(_pose(d.p)))
    other = d.signed(d.body(request(Action.POSE, d.p.codec.pose_blocks([OTHER_POSE]))))
    short = whole[:-SHORT_BY]
    if not d.zeros(d.ask(lab, whole, wait_s, "a pose datagram whole"), Action.POSE):
        return
    if not d.zeros(d.ask(lab, short, wait_s, f"the same pose datagram short of its last {SHORT_BY} bytes"),
                   Action.POSE):
        lab.tried.append(f"a pose datagram short of {SHORT_BY} bytes, right after it came whole: dropped")
        return
    d.ask(lab, other, wait_s, "another pose datagram whole (other values)")
    after_other = d.zeros(d.ask(lab, short, wait_s, f"the first pose datagram short of {SHORT_BY} bytes, after the "
                                "other one"), Action.POSE)
    d.ask(lab, whole, wait_s, "the first pose datagram whole again")
    again = d.zeros(d.ask(lab, short, wait_s, f"short of {SHORT_BY} bytes again, right after it came whole"),
                    Action.POSE)
    if again and not after_other:
        lab.found("udp-short-completed", missing=SHORT_BY, size=len(short), frame=len(whole))


def tcp_check(p: Prober, lab: Lab, found: tuple[str, ByteOrder] | None = None) -> None:
    ex = p.exchange([p.valid_request(int(Action.NONE))], settle=False)
    if ex is None or not ex.reached:
        return
    lab.experiment.exchanges.append(ex)
    answers = ex.reading(0).answers
    if not answers or len(answers[0].raw) < HEADER_LEN + CHECK_LEN:
        return
    raw = answers[0].raw
    head = peek_header(raw, 0, p.profile.byte_order)
    end = HEADER_LEN + (head.block_count * head.block_length if head else 0)
    check = raw[end:end + CHECK_LEN]
    if len(check) == CHECK_LEN and check != b"\0\0":
        lab.found("tcp-check-field", check=check.hex(" "), matches=crc_matches(raw[:end], check))
    crc_refused(p, lab, found)


def _pose_zero(p: Prober, data: bytes) -> bool | None:
    """A pose then a NONE on a fresh connection: the pose answered 0000 (None: nothing heard)."""
    ex = p.exchange([data, p.valid_request(int(Action.NONE))], quiet=[True, False], settle=False)
    if ex is None or not ex.reached:
        return None
    lab_answers = ex.reading(0).answers
    if not lab_answers and not ex.reading(1).answers:
        return None
    return bool(lab_answers) and lab_answers[0].action == Action.POSE and lab_answers[0].error == 0


def crc_refused(p: Prober, lab: Lab, found: tuple[str, ByteOrder] | None) -> None:
    """F6 (SHOULD): a pose with 00 00 accepted, the same pose with its CRC in the check field refused? Then, when
    UDP showed the box's own CRC, is the pose with that one accepted (it checks the TCP check field with it)?"""
    plain = p.valid_request(int(Action.POSE))
    signed = plain[:-2] + p.profile.check_bytes(plain[:-2])
    if not (_pose_zero(p, plain) and _pose_zero(p, signed) is False):
        return
    own = None
    if found is not None:
        theirs = plain[:-2] + crc_function(found[0])(plain[:-2]).to_bytes(2, found[1])
        own = found[0] if _pose_zero(p, theirs) else None
    lab.found("tcp-crc-refused", check=signed[-2:].hex(" "), crc=p.profile.crc, own=own)


def run(p: Prober, udp_target: Target | None, causes: Sequence[RootCause]) -> Lab:
    """The experiments the causes need (UDP ones with a UDP target; the TCP check field when F6 failed)."""
    lab = Lab(Experiment("udp", "datagrams from an unconnected socket (its neighbouring ports listening): where the "
                                "answers go, which CRC is checked and signed, what it covers, frames per datagram; "
                                "the TCP check field"))
    kinds = {c.kind for c in causes}
    found = None
    if UDP in kinds and udp_target is not None:
        with UdpProbe(udp_target, p.dialer.transcript) as u:
            found = _udp(p, lab, _Datagrams(p, u, time.monotonic() + max(MIN_LEFT_S, SHARE * p.left())))
    if TCP_CHECK in kinds:
        tcp_check(p, lab, found)
    return lab


def _udp(p: Prober, lab: Lab, d: _Datagrams) -> tuple[str, ByteOrder] | None:
    """The UDP experiments in order; the (CRC, byte order) found when it is not the profile's."""
    wait = min(p.dialer.time_out_s, CONFIRM_WAIT_S * 2)
    none = d.body(request(Action.NONE))
    base = d.ask(lab, d.signed(none), wait, "NONE datagram, the profile's CRC")
    if base is None:
        return None
    where_answers_go(d, lab, base)
    if lab.has("udp-answer-port", "udp-answer-source"):
        return None
    if not d.zeros(base, Action.NONE):
        found = scan_crc(d, lab, none)
        if found is None:
            alive = p.exchange([p.valid_request(int(Action.NONE))], settle=False)
            if alive is not None and alive.reached and alive.reading(0).answers:
                lab.found("udp-silent", tried=len(candidates(d.crc, d.order)) + 1)
            return None
        again = d.ask(lab, d.signed(none, *found), CONFIRM_WAIT_S, "NONE datagram under the CRC found")
        signs = bool(again and again.heard and again.heard[0].data[-2:] ==
                     d.signed(again.heard[0].data[:-2], *found)[-2:])
        kind = "udp-crc-byte-order" if found[0] == d.crc else "udp-crc-algorithm"
        lab.found(kind, crc=found[0], order=found[1], profile=d.crc, signs=signs, order_differs=found[1] != d.order)
        return found
    answer_shape(d, lab, base)
    bad = d.ask(lab, none + _no_crc_value(none), wait, "NONE datagram, a check no CRC-16 computes")
    if d.zeros(bad, Action.NONE):
        lab.found("udp-crc-unchecked", check=_no_crc_value(none).hex(" "))
    else:
        one_byte(d, lab, none)
        coverage(d, lab, wait)
    datagram_length(d, lab, wait)
    short_after_whole(d, lab, wait)
    return None


def assign(cause: RootCause, lab: Lab) -> None:
    """The cause titled by its family's first mechanism (or "unconfirmed"), with its diagnosis."""
    wanted = TCP_KINDS if cause.kind == TCP_CHECK else tuple(k for k in ORDER if k not in TCP_KINDS)
    mine = sorted((m for m in lab.mechanisms if m.kind in wanted), key=lambda m: ORDER.index(m.kind))
    chosen = mine[0] if mine else None
    original = cause.title
    hyps = [Hypothesis(m.kind, m.title, Status.CONFIRMED if m is chosen else Status.CONSISTENT, lab.experiment.name)
            for m in mine]
    hyps += [Hypothesis("tried", what, Status.RULED_OUT, lab.experiment.name) for what in lab.tried]
    if chosen is None:
        cause.confirmed, cause.title = False, titles.unconfirmed(original)
    else:
        cause.confirmed, cause.title, cause.clauses = True, chosen.title, chosen.clauses
    lab.experiment.finding = lab.experiment.finding or "; ".join(m.kind for m in mine) or "no mechanism confirmed"
    cause.diagnosis = {"confirmed": cause.confirmed, "mechanism": chosen.kind if chosen else None,
                       "catalogue_title": original, "detail": chosen.to_dict() if chosen else {},
                       "hypotheses": [h.to_dict() for h in hyps], "experiments": [lab.experiment.to_dict()]}
