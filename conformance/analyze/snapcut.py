"""Frames the capture cut short: packets kept only up to the capture's snap length (``tcpdump -s 64``).

The packet's length is known (its IP header), so the bytes the capture did not keep are a
known count at a known place, not a gap: the frame reader (:mod:`.framing`) goes on framing
after them, and a frame whose first bytes were kept, its header up to the block length at
least (bytes 0-9: start word, version, transfer type, action, block type, N, L), becomes a
:class:`SnapCut`. It is judged on what it shows: its action pairs it with its request or
answer (A1, A2), its time is the latency's (T1) and the stream's clock (T2), its action is a
step of the session (S1, E4). What was not kept (the error code when fewer than 12 bytes
were, the blocks, the check field) is not judged: each such frame is INCONCLUSIVE under F5,
with the reason. Sans-I/O.
"""

from __future__ import annotations

from typing import Any

from ..model.verdicts import Verdict
from ..protocol import Action, ProtocolError, codec_for
from ..protocol.answers import Expectation, Rule
from ..protocol.constants import HEADER_LEN, START_WORD, VERSION
from ..protocol.profile import Profile
from .findings import ROBOT

__all__ = ["HEADER_KNOWN", "SnapCut", "cut_counts", "note_cut", "snap_expectation", "span_of_prefix"]

#: the bytes of a header that tell the frame's length (up to and with the block length L)
HEADER_KNOWN = 10


class SnapCut(ProtocolError):
    """A frame of ``size`` bytes of which the capture kept the first ``len(raw)`` (its snap length cut the rest)."""

    clause = "F5"

    def __init__(self, prefix: bytes, size: int, profile: Profile, offset: int = 0) -> None:
        kept = len(prefix)
        header = codec_for(profile).parse_header((bytes(prefix) + bytes(HEADER_LEN))[:HEADER_LEN])
        what = f"{_name(header.action)} frame of {size} bytes"
        super().__init__(f"{what} cut by the capture's snap length after {kept} byte(s): "
                         f"{'its blocks and check field' if kept >= HEADER_LEN else 'its error code, blocks and check field'}"
                         " are not in the capture", offset=offset, raw=prefix, header=header)
        self.size = size
        self.kept = kept

    @property
    def action(self) -> Action | None:
        """The frame's action, when its header is a request or answer header (FE FE, 00 01, a known action)."""
        h = self.header
        if h is None or h.start_word != START_WORD or h.version != VERSION:
            return None
        try:
            return Action(h.action)
        except ValueError:
            return None

    @property
    def error_code(self) -> int | None:
        """The error code, when the capture kept it (bytes 10-11)."""
        return self.header.error_code if self.header is not None and self.kept >= HEADER_LEN else None

    blocks: tuple[Any, ...] = ()


def _name(action: int) -> str:
    try:
        return f"a {Action(action).name}"
    except ValueError:
        return f"a 0x{action:02X}"


def span_of_prefix(prefix: bytes, span: Any) -> int:
    """The length of the frame whose first bytes are ``prefix`` (``span``: the profile's frame spanner), or 0 when
    they do not tell it (fewer than :data:`HEADER_KNOWN` bytes, or no plausible header there)."""
    if len(prefix) < HEADER_KNOWN:
        return 0
    total = int(span(prefix + bytes(HEADER_LEN - min(len(prefix), HEADER_LEN)), 0))
    return total if total > 0 else 0


def snap_expectation(event: SnapCut) -> Expectation:
    """A request the capture cut short: its content is unknown, so any answer is allowed (only pairing is judged)."""
    return Expectation(Rule.ANY, "F5", event.action, event.message)


def note_cut(j: Any, event: SnapCut, frames: tuple[int, ...], side: str) -> int | None:
    """File the cut frame INCONCLUSIVE under F5 of its sender (``j``: the connection's judge) and count it by action
    (:func:`cut_counts`); the action its header names, to pair and time it by (None: not a request or answer)."""
    raw = {"robot": bytes(event.raw)} if side == ROBOT else {"box": bytes(event.raw)}
    j.findings.add("F5", side, Verdict.INCONCLUSIVE, f"{j.label}, offset {event.offset}: {event.message}", frames,
                   **raw)
    action = event.action
    if action is not None:
        counts = cut_counts(j, side)
        counts[action] = counts.get(action, 0) + 1
    return action


def cut_counts(j: Any, side: str) -> dict[int, int]:
    """The frames of ``side`` the capture cut, by action (their content is not judged: F6, B1-B4, E1-E3)."""
    per_side: dict[str, dict[int, int]] = j.__dict__.setdefault("snap_cuts", {})
    return per_side.setdefault(side, {})
