"""The fuzz oracle: what PROTOCOL.md lets a box do with some bytes, and whether it did.

The facts live in :mod:`conformance.protocol`: what a box may do with one event
(:mod:`~conformance.protocol.answers`: a well-formed request MUST be answered with an
allowed code, a parse error MUST NOT be answered 0000 and SHOULD get A3's error, bytes
that are not a request may get silence, an error or a close, ...) and the legal
framings of bad bytes (:mod:`~conformance.protocol.framings`). This module adapts them
to the harness's outcomes:

* :func:`expectations` decodes the bytes with the reference framing (the codec's
  :class:`~conformance.protocol.StreamDecoder`): the events strategies and reports name,
  and the zero *filler* that completes a frame the bytes leave open, so that the probe
  sent behind them starts on a frame boundary for a box that trusts headers;
* :func:`judge` compares what the box did (its answers, in order, and how the exchange
  ended) with every legal framing of the bytes sent and reports what *no* legal
  framing explains: FAIL for a broken MUST, NON-STRICT for a broken SHOULD.
"""


from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

from ..harness.client import Answer, Closed, Malformed, Outcome, Silence
from ..harness.exchange import seen_of
from ..model.verdicts import Verdict, broken_verdict
from ..protocol import (
    HEADER_LEN,
    Frame,
    Profile,
    ProtocolError,
    StreamDecoder,
    TransferType,
    Transport,
    decode_datagram,
    peek_header,
)
from ..protocol.answers import (
    CONFLICT,
    NOT_UNDERSTOOD,
    Expectation,
    Rule,
    request_action,
    rule_for_error,
    rule_for_frame,
)
from ..protocol.answers import Finding as RawFinding
from ..protocol.explain import explain, explain_events
from ..protocol.framings import End, Explanation

__all__ = ["CONFLICT", "NOT_UNDERSTOOD", "Expectation", "Finding", "Judgement", "Rule", "expectations", "judge",
           "request_action", "seen_of"]


@dataclass(frozen=True, slots=True)
class Finding:
    verdict: Verdict  # FAIL (a MUST) or NON_STRICT (a SHOULD)
    clause: str
    requirement: str
    observed: str
    key: str = ""  # what failed, for telling distinct failures apart: clause/rule/action

    def describe(self) -> str:
        return f"{self.verdict.value} [{self.clause}] {self.requirement}; the box {self.observed}"


@dataclass
class Judgement:
    findings: list[Finding] = field(default_factory=list)
    explanation: Explanation | None = None  # the legal framing that explains the box best (TCP bytes)

    @property
    def verdict(self) -> Verdict:
        if any(f.verdict is Verdict.FAIL for f in self.findings):
            return Verdict.FAIL
        return Verdict.NON_STRICT if self.findings else Verdict.PASS

    @property
    def failures(self) -> list[Finding]:
        return [f for f in self.findings if f.verdict is Verdict.FAIL]

    def describe(self) -> str:
        return "; ".join(f.describe() for f in self.findings) or "as PROTOCOL.md allows"


# -- expectations (the reference framing) -------------------------------------------------------------


def _completion(decoder: StreamDecoder) -> int:
    """Zero bytes that complete the partial frame the decoder holds (at least one)."""
    buffered = decoder.buffered
    if buffered < HEADER_LEN:
        return HEADER_LEN - buffered
    head = peek_header(decoder._buf, decoder._pos, decoder.profile.byte_order)  # noqa: SLF001 - the header it waits on
    assert head is not None  # at least HEADER_LEN bytes are buffered
    return max(1, head.frame_length - buffered)


def expectations(
    data: bytes,
    profile: Profile,
    transport: Transport = Transport.TCP,
    extension: bool = True,
    eof: bool = False,
) -> tuple[bytes, tuple[Expectation, ...]]:
    """(filler, one expectation per event of the reference framing) for ``data`` sent to a box.

    TCP: the stream decoder's events; ``eof`` ends the stream after ``data`` (a
    truncated frame then is an F5 error), else a frame left incomplete is completed
    with zero filler bytes (returned; send them after ``data``). UDP: ``data`` is one
    datagram (F7, R7)."""
    if transport is Transport.UDP:
        try:
            events: list[Frame | ProtocolError] = [decode_datagram(data, profile, TransferType.ROBOT_TO_BOX)]
        except ProtocolError as exc:
            events = [exc]
        filler = b""
    else:
        decoder = StreamDecoder(profile, TransferType.ROBOT_TO_BOX)
        events = decoder.feed(data)
        filler = b""
        if eof:
            decoder.receive_data(b"")
            events += list(decoder.events())
        else:
            for _ in range(8):  # a header, then its body: two rounds suffice; bounded anyway
                if not decoder.buffered:
                    break
                more = bytes(_completion(decoder))
                filler += more
                events += decoder.feed(more)
    out: list[Expectation] = []
    seen_error = False
    for event in events:
        if isinstance(event, Frame):
            exp = rule_for_frame(event, profile, transport, extension)
        else:
            exp = rule_for_error(event, profile, transport, extension)
        if seen_error:
            exp = exp.after()
        seen_error = seen_error or not exp.valid
        out.append(exp)
    return filler, tuple(out)


# -- judging -------------------------------------------------------------------------------------------


def _end(end: Outcome | None) -> tuple[End, str]:
    if isinstance(end, Closed):
        return End.CLOSED, end.describe()
    if isinstance(end, Silence):
        return End.SILENT, f"{end.describe()} (nothing more came, not even the probe's answer)"
    return End.ANSWERED, "went on to answer the probe" if isinstance(end, Answer) else "went on"


def judge(
    expects: Sequence[Expectation],
    outcomes: Sequence[Outcome],
    end: Outcome | None,
    profile: Profile,
    probe_action: int | None = None,
    *,
    data: bytes | None = None,
    extension: bool = True,
    eof: bool = False,
    transport: Transport = Transport.TCP,
    probe_at: int | None = None,
) -> Judgement:
    """Judge what the box did with some bytes.

    ``outcomes``: the answers (and malformed answers) that came before the probe's
    answer, in order. ``end``: the probe's answer, or Closed / Silence when the exchange
    ended otherwise (None: nothing more is judged). ``data``: every byte sent on the
    TCP connection, the probe's included: the box is then judged against every legal
    framing of them. Without ``data`` the events are ``expects`` (and the probe, when
    ``probe_action`` is given), in order: UDP datagrams, or a session's requests."""
    answers = [o for o in outcomes if isinstance(o, (Answer, Malformed))]
    if isinstance(end, (Answer, Malformed)):
        answers.append(end)
    seen = [seen_of(o, profile) for o in answers]
    kind, text = _end(end)
    if data is not None and transport is Transport.TCP:
        exp = explain(data, seen, kind, profile, extension=extension, eof=eof, end_text=text, probe_at=probe_at)
    else:
        events = list(expects)
        if probe_action is not None:
            events.append(Expectation(Rule.ANSWER, "", int(probe_action), "the valid probe request behind the bytes",
                                      ok_errors=frozenset({0}), probe=True))
        events = [replace(e, after_error=False) for e in events]  # the search tracks garbage itself
        exp = explain_events(events, seen, kind, text, independent=transport is Transport.UDP)
    return Judgement([_finding(f) for f in exp.findings], exp)


def _finding(f: RawFinding) -> Finding:
    return Finding(broken_verdict(f.level), f.clause, f.requirement, f.observed, f.key)
