"""Which input a death followed: a box that stopped accepting (or answering) new connections after a case is
named with what that case sent — a header announcing more block bytes than the largest legal frame, or the
first bytes of the input — instead of the case's id alone (issue 34: "after the input of case FUZZ-01: which
input?"). Pure: the session already proved the death on fresh connections, and the phase checked it again."""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path

from ..i18n import gettext
from ..model.verdicts import CaseResult, RootCause
from ..protocol import Profile, ProtocolError, codec_for
from ..protocol.constants import HEADER_LEN, MAX_FRAME_LEN, START_BYTES

DEATHS = ("connection-leak", "dead-after-input")
#: a fuzz finding names its vector file: the whole sequence of inputs that preceded the death
_VECTOR = re.compile(r"vector (\S+?\.json)")
_MAX_VECTOR_BYTES = 4 << 20


def inputs(case: CaseResult) -> list[bytes]:
    """The inputs a case sent, as far as its verdict quotes them and its fuzz vector file (if any) holds them."""
    out: list[bytes] = []
    try:
        out.append(bytes.fromhex(case.sent_hex.partition("…")[0]))
    except ValueError:
        pass
    found = _VECTOR.search(case.message or "")
    path = Path(found.group(1)) if found else None
    if path is not None and path.is_file() and path.stat().st_size <= _MAX_VECTOR_BYTES:
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
            out += [bytes.fromhex(t["hex"]) for g in doc.get("testGroups", []) for t in g.get("tests", [])
                    if isinstance(t.get("hex"), str)]
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            pass
    return [b for b in out if b]


def oversize(data: bytes) -> tuple[int, int] | None:
    """(block count, block length) of the first header in ``data`` announcing more than the largest legal frame."""
    at = data.find(START_BYTES)
    while 0 <= at <= len(data) - HEADER_LEN:
        count, length = data[at + 7], data[at + 8] << 8 | data[at + 9]
        if HEADER_LEN + count * length + 2 > MAX_FRAME_LEN:
            return count, length
        at = data.find(START_BYTES, at + 1)
    return None


def name(causes: Sequence[RootCause], cases: Sequence[CaseResult]) -> None:
    """Retitle each confirmed death with the input that preceded it (in place)."""
    by_id = {c.id: c for c in cases}
    for cause in causes:
        if cause.kind not in DEATHS or not cause.confirmed:
            continue
        killer = next((by_id[i] for i in cause.cases if i in by_id and by_id[i].sent_hex), None)
        if killer is None:
            continue
        sent = inputs(killer)
        if not sent:
            continue
        data = sent[0]
        still = gettext(" (connections already open are still served)") if cause.kind == "connection-leak" else ""
        big = next((b for b in map(oversize, sent) if b is not None), None)
        if big is not None:
            cause.title = gettext(
                "Stops accepting new connections after a header announcing {n} × {length} block bytes (case {case}), a "
                "length beyond the largest legal frame of {max} bytes{still}: R2/R5 ask that no input stops the box "
                "— skip or refuse an oversize header without touching the listening socket").format(
                n=big[0], length=big[1], case=killer.id, max=MAX_FRAME_LEN, still=still)
        else:
            shown = data[:16].hex(" ") + (" …" if len(data) > 16 else "") + _problem(data)
            cause.title = gettext("Stops accepting new connections after the input of case {case} ({hex}){still}: R2 "
                                  "asks that no input stops the box — survive that input").format(
                case=killer.id, hex=shown, still=still)


def _problem(data: bytes) -> str:
    """What is wrong with the input's first frame, as the codec says it ("" when it is a valid request)."""
    try:
        codec_for(Profile()).parse(data[:codec_for(Profile()).frame_length(data)] if len(data) >= HEADER_LEN else data)
    except ProtocolError as exc:
        return f": {str(exc).split(' (at offset')[0]}"
    except (ValueError, IndexError):
        return ""
    return ""
