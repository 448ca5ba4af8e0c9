"""conformance.engine.wirelog: a case's transcript as report lines, decoded, and bounded (head, tail, hex)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from conformance.engine.wirelog import MAX_DECODED, MAX_EVENTS, MAX_HEX_BYTES, MAX_LINES, TAIL_LINES, wire_lines
from conformance.harness.transcript import Endpoint, Kind, Transcript
from conformance.model.verdicts import WireLine
from conformance.protocol import Action, Profile, Transport, answer, encode, request

PROFILE = Profile()
NONE_REQUEST = encode(request(Action.NONE))
NONE_ANSWER = encode(answer(Action.NONE))


def ticking(step: float = 0.001) -> Callable[[], float]:
    """A clock that moves ``step`` seconds per reading: every event's time is known."""
    now = [100.0]

    def clock() -> float:
        now[0] += step
        return now[0]

    return clock


def transcript_with(transport: str = "tcp") -> Transcript:
    transcript = Transcript("W-1", clock=ticking())
    transcript.open(transport, Endpoint("127.0.0.1", 5000), Endpoint("127.0.0.1", 9004), "command")
    return transcript


def notes(count: int, transcript: Transcript | None = None) -> Transcript:
    """A transcript of ``count`` numbered note events on connection 1."""
    transcript = transcript or transcript_with()
    for i in range(count):
        transcript.add(1, Kind.NOTE, note=f"n{i}")
    return transcript


def numbers(lines: list[WireLine]) -> list[int]:
    return [int(line.summary[1:]) for line in lines if line.summary.startswith("n")]


# -- one line per event ----------------------------------------------------------------------------


def test_a_short_exchange_is_one_decoded_line_per_event() -> None:
    t = transcript_with()
    t.add(1, Kind.CONNECT, note="command connected")
    t.add(1, Kind.SEND, NONE_REQUEST, "NONE request")
    t.add(1, Kind.RECV, NONE_ANSWER)
    t.add(1, Kind.CLOSE)
    lines = wire_lines(t, PROFILE)
    assert [(w.direction, w.kind, w.conn) for w in lines] == [
        ("·", Kind.CONNECT, 1), ("→", Kind.SEND, 1), ("←", Kind.RECV, 1), ("·", Kind.CLOSE, 1)]
    assert [w.t_ms for w in lines] == [0.0, 1.0, 2.0, 3.0]  # since the case's first event
    assert lines[0].summary == "command connected (command, tcp 127.0.0.1:5000 → 127.0.0.1:9004)"
    assert lines[1].hex == "fe fe 00 01 01 00 00 00 00 00 00 00 00 00"
    assert lines[1].summary == "NONE request: robot→box NONE err=0x0000"
    assert lines[2].hex == "fe fe 00 01 10 00 00 00 00 00 00 00 00 00"
    assert lines[2].summary == "box→robot NONE err=0x0000"
    assert lines[3].hex == "" and lines[3].summary == ""


def test_bytes_the_wrong_way_round_are_named_by_their_clause() -> None:
    t = transcript_with()
    t.add(1, Kind.RECV, NONE_REQUEST)  # a request coming from the box
    t.add(1, Kind.SEND, b"hello, box!!")  # no start word
    received, sent = wire_lines(t, PROFILE)
    assert received.summary.startswith("[F3] transfer type 0x01, expected 0x10")
    assert sent.summary.startswith("[F1] 68 65 where a start word fe fe was expected")


def test_a_frame_split_over_chunks_is_decoded_when_it_is_whole() -> None:
    t = transcript_with()
    t.add(1, Kind.SEND, NONE_REQUEST[:5])
    t.add(1, Kind.RECV, NONE_ANSWER)  # the other direction has its own decoder
    t.add(1, Kind.SEND, NONE_REQUEST[5:])
    first, answer_line, rest = wire_lines(t, PROFILE)
    assert first.summary == "(5 bytes of an incomplete frame)"
    assert answer_line.summary == "box→robot NONE err=0x0000"
    assert rest.summary == "robot→box NONE err=0x0000"


def test_every_connection_has_its_own_decoder() -> None:
    t = transcript_with()
    t.open("tcp", Endpoint("127.0.0.1", 5001), Endpoint("127.0.0.1", 9004), "stream")
    t.add(1, Kind.SEND, NONE_REQUEST[:7])
    t.add(2, Kind.SEND, NONE_REQUEST)  # whole on connection 2, whatever 1 left hanging
    assert wire_lines(t, PROFILE)[1].summary == "robot→box NONE err=0x0000"


def test_many_frames_in_one_chunk_name_a_few_and_count_the_rest() -> None:
    t = transcript_with()
    t.add(1, Kind.SEND, NONE_REQUEST * 18)  # 252 bytes: all shown in hex
    (line,) = wire_lines(t, PROFILE)
    parts = line.summary.split("; ")
    assert parts[:MAX_EVENTS] == ["robot→box NONE err=0x0000"] * MAX_EVENTS
    assert parts[MAX_EVENTS:] == [f"… and {18 - MAX_EVENTS} more"]


def test_a_long_chunk_shows_its_first_bytes_in_hex_and_says_so() -> None:
    t = transcript_with()
    t.add(1, Kind.SEND, NONE_REQUEST * 100)  # 1400 bytes
    t.add(1, Kind.SEND, bytes(MAX_HEX_BYTES))  # exactly the bound: shown whole
    long, exact = wire_lines(t, PROFILE)
    assert long.hex == (NONE_REQUEST * 100)[:MAX_HEX_BYTES].hex(" ") and len(long.hex.split()) == MAX_HEX_BYTES
    assert long.summary.endswith(f"[1400 bytes: the first {MAX_HEX_BYTES} shown]")
    assert len(exact.hex.split()) == MAX_HEX_BYTES and "shown" not in exact.summary


def test_udp_datagrams_are_decoded_one_by_one() -> None:
    t = transcript_with("udp")
    good = encode(request(Action.NONE), PROFILE, Transport.UDP)
    t.add(1, Kind.SEND, good[:7], "half a datagram")
    t.add(1, Kind.SEND, good)
    half, whole = wire_lines(t, PROFILE)
    assert half.summary.startswith("half a datagram: [F")  # a datagram is a frame: half of one is an error
    assert whole.summary == "robot→box NONE err=0x0000"


def test_notes_keep_their_words() -> None:
    t = transcript_with()
    t.note("step 1: the suite begins")  # connection 0: the case itself
    (line,) = wire_lines(t, PROFILE)
    assert (line.direction, line.kind, line.conn, line.hex, line.summary) == (
        "·", Kind.NOTE, 0, "", "step 1: the suite begins")


# -- the bounds --------------------------------------------------------------------------------------


def test_the_bounds_are_those_the_reports_promise() -> None:
    assert (MAX_LINES, TAIL_LINES, MAX_HEX_BYTES) == (300, 100, 256)


@pytest.mark.parametrize("count", [0, 1, MAX_LINES, MAX_LINES + 1, MAX_LINES + TAIL_LINES])
def test_a_log_that_fits_is_kept_whole(count: int) -> None:
    lines = wire_lines(notes(count), PROFILE)
    assert numbers(lines) == list(range(count)) and len(lines) == count


def test_a_long_log_keeps_its_head_and_tail_and_counts_what_is_left_out() -> None:
    count = MAX_LINES + TAIL_LINES + 600
    lines = wire_lines(notes(count), PROFILE)
    assert len(lines) == MAX_LINES + 1 + TAIL_LINES
    assert numbers(lines[:MAX_LINES]) == list(range(MAX_LINES))
    assert numbers(lines[MAX_LINES + 1:]) == list(range(count - TAIL_LINES, count))
    cut = lines[MAX_LINES]
    assert (cut.direction, cut.kind, cut.hex) == ("·", "note", "")
    assert cut.summary == "… 600 more events (not shown; see the pcap)"


def test_the_head_and_tail_sizes_are_parameters() -> None:
    lines = wire_lines(notes(10), PROFILE, limit=3, tail=2)
    assert numbers(lines) == [0, 1, 2, 8, 9] and lines[3].summary == "… 5 more events (not shown; see the pcap)"
    only_count = wire_lines(notes(10), PROFILE, limit=0, tail=0)
    assert [w.summary for w in only_count] == ["… 10 more events (not shown; see the pcap)"]


def test_the_tail_is_decoded_in_step_with_what_was_left_out() -> None:
    t = transcript_with()
    t.add(1, Kind.SEND, NONE_REQUEST[:3])  # in the head
    notes(MAX_LINES + TAIL_LINES, t)
    t.add(1, Kind.SEND, NONE_REQUEST[3:] + NONE_REQUEST[:9])  # in the tail: the rest, then most of another
    lines = wire_lines(t, PROFILE)
    assert lines[0].summary == "(3 bytes of an incomplete frame)"
    assert lines[-1].summary == "robot→box NONE err=0x0000; (9 bytes of an incomplete frame)"


def flood(count: int) -> Transcript:
    """``count`` chunks of 1000 garbage-and-frame bytes each, as a box flooding the suite sends them."""
    t = transcript_with()
    chunk = (b"\xfe\xfe\x00\x02" + NONE_ANSWER) * 55 + bytes(10)  # 1000 bytes: a bad version, a frame, again
    for _ in range(count):
        t.add(1, Kind.RECV, chunk)
    return t


def size(lines: list[WireLine]) -> int:
    return sum(len(w.hex) + len(w.summary) for w in lines)


def without_cut(lines: list[WireLine]) -> list[WireLine]:
    return lines[:MAX_LINES] + lines[MAX_LINES + 1:]


def test_a_flood_gives_a_log_of_bounded_size_that_says_how_much_was_left_out() -> None:
    small, large = wire_lines(flood(450), PROFILE), wire_lines(flood(1_500), PROFILE)  # 1.5 MB: all recorded
    assert len(small) == len(large) == MAX_LINES + 1 + TAIL_LINES
    assert small[MAX_LINES].summary == f"… {450 - MAX_LINES - TAIL_LINES} more events (not shown; see the pcap)"
    assert large[MAX_LINES].summary == f"… {1_500 - MAX_LINES - TAIL_LINES} more events (not shown; see the pcap)"
    assert size(without_cut(large)) == size(without_cut(small))  # more input, not one character more of log
    decoded = [line for line in without_cut(large) if "not decoded" not in line.summary]  # the first events
    assert len(decoded) == MAX_DECODED // 111
    for line in without_cut(large):
        assert len(line.hex) <= 3 * MAX_HEX_BYTES
    for line in decoded:
        assert line.summary.count("[F2]") + line.summary.count("NONE") == MAX_EVENTS  # 111 events: 8 named
        assert f"… and {2 * 55 + 1 - MAX_EVENTS} more [" in line.summary  # ... the rest counted
    assert large[1].summary.endswith(f"[1000 bytes: the first {MAX_HEX_BYTES} shown]")


def test_a_flood_is_decoded_up_to_a_bound_per_case_and_the_lines_say_so() -> None:
    """A box flooding headers sends megabytes, millions of events: the case's first MAX_DECODED events are
    decoded, the lines after say they are not (the pcap has them)."""
    transcript = transcript_with()
    transcript.open("tcp", Endpoint("127.0.0.1", 5001), Endpoint("127.0.0.1", 9004), "other")
    transcript.add(2, Kind.RECV, NONE_ANSWER)
    header = bytes.fromhex("fe fe 00 01 10 23 ff ff ff 00 00 00")  # 255 x 65535 announced: an oversized header
    for _ in range(3):
        transcript.add(1, Kind.RECV, header * (MAX_DECODED // 2))
    lines = wire_lines(transcript, PROFILE)
    assert "NONE" in next(line for line in lines if line.conn == 2 and line.kind == Kind.RECV).summary
    first, second, third = (line.summary for line in lines if line.conn == 1 and line.kind == Kind.RECV)
    assert "skipped" in first and "not decoded" not in first
    assert f"… and {MAX_DECODED // 2 - MAX_EVENTS} more" in first
    assert "skipped" in second and "(the rest not decoded: the case's first 1000 events are" in second
    assert third.startswith("(not decoded: the case's first 1000 events are; the pcap has every byte)")
