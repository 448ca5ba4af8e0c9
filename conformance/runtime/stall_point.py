"""Where a stall of the whole box began, read from the case's own wire: the request of its last write that the box
left unanswered, when it is the only one (answers come in order, A1: every request before it was answered, so the
box went silent while that request was the only one pending). Pure: the bytes written and the bytes received
after them in, the request's action out."""

from __future__ import annotations

from ..protocol import parse_header
from ..protocol.constants import HEADER_LEN, START_WORD

#: actions in the protocol's words (as the diagnose titles write them)
WORDS = {0x00: "NONE", 0x01: "CycleOn", 0x02: "CycleOff", 0x23: "pose", 0x24: "register pose", 0x25: "tolerance",
         0x26: "ProgIdx", 0x27: "result request"}


def frames(data: bytes) -> list[int]:
    """The actions of the whole frames ``data`` starts with, in order (stops at bytes that are not a frame)."""
    out: list[int] = []
    at = 0
    while len(data) - at >= HEADER_LEN:
        header = parse_header(data[at:at + HEADER_LEN])
        if header.start_word != START_WORD:
            break
        size = HEADER_LEN + header.block_count * header.block_length + 2
        if len(data) - at < size:
            break
        out.append(header.action)
        at += size
    return out


def first_unanswered(sent: bytes, received: bytes) -> int | None:
    """The action of the one request in ``sent`` that ``received`` (the answers heard after it was written) leaves
    unanswered. None when every request was answered, when several were not (a box whose loop blocks may hold the
    answers it already wrote: the request it blocked on is then not told by the wire), or ``sent`` holds none."""
    asked, answered = frames(sent), len(frames(received))
    return asked[answered] if answered == len(asked) - 1 else None


def word(action: int) -> str:
    return f"{WORDS.get(action, f'0x{action:02X}')} ({action:02X})"
