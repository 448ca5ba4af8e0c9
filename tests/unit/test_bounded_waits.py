"""What the engine learns from waits (harness/waits.py, harness/quiet.py's refused pattern), and the T2 excess figures."""

from __future__ import annotations

from conformance.harness.quiet import CUT_S, Hangs, refused_key
from conformance.harness.starvation import Stall, StarvationGauge, explains, starved_verdict
from conformance.harness.waits import REPEAT, RanOut
from conformance.observed.stream_timing import jitter_excess_ms, rate_excess_ms, stream_stats


def test_a_place_counts_only_when_its_case_failed_on_the_silence() -> None:
    ran_out = RanOut()
    for n in range(REPEAT):
        ran_out.ran_out(f"legal-{n}", 6)
        ran_out.case_ended(f"legal-{n}", failed_on_silence=False)  # a legal silence: learns nothing
    assert ran_out.known(6) is None and ran_out.bound(6, 5.0) is None
    for n in range(REPEAT):
        ran_out.ran_out(f"case-{n}", 6)
        ran_out.case_ended(f"case-{n}", failed_on_silence=True)
    assert ran_out.known(6) == [f"case-{n}" for n in range(REPEAT)]
    assert ran_out.bound(6, 5.0) == CUT_S and ran_out.bound(6, 0.1) == 0.1
    assert ran_out.bound(5, 5.0) is None  # another place on the connection is not cut


def test_an_answer_at_the_place_withdraws_the_pattern() -> None:
    ran_out = RanOut()
    for n in range(REPEAT):
        ran_out.ran_out(f"case-{n}", 13)
        ran_out.case_ended(f"case-{n}", failed_on_silence=True)
    ran_out.answered_at(13)
    assert ran_out.known(13) is None


def test_the_refused_pattern_bounds_the_family_and_is_withdrawn_by_a_late_zero() -> None:
    hangs = Hangs()
    key = refused_key("reject")
    assert key == refused_key("reject-should") != refused_key("not-request")  # one family for requests
    for n in range(2):
        hangs.note(key, f"case-{n}", hung=True, probe_answered=False)
    assert hangs.bound("reject", False, 5.0) == CUT_S
    assert hangs.bound("reject", True, 5.0) is None  # a case that judges R6 itself waits in full
    assert hangs.bound("not-request", False, 5.0) is None
    hangs.withdraw_refused("reject")
    assert hangs.bound("reject", False, 5.0) is None


def test_a_stall_explains_a_breach_no_larger_than_itself() -> None:
    gauge = StarvationGauge()
    gauge.note(100.0, 150.0)  # the timer woke 150 ms late at t=100 s
    assert gauge.worst_ms(99.0, 101.0) == 150.0 and gauge.worst_ms(101.0, 102.0) == 0.0
    assert explains(120.0, 150.0) and not explains(200.0, 150.0) and not explains(0.5, 1.0)
    assert starved_verdict(120.0, 99.0, 101.0, source=gauge) is not None
    assert starved_verdict(400.0, 99.0, 101.0, source=gauge) is None
    assert starved_verdict(120.0, 200.0, 201.0, source=gauge) is None
    assert Stall(1.0, 2.0).wall == 0.0


def _stream(rate_hz: float, seconds: float = 3.0) -> list[float]:
    return [i / rate_hz for i in range(int(rate_hz * seconds))]


def test_a_slow_stream_is_off_by_more_than_a_stall_could_hide() -> None:
    slow = stream_stats(_stream(45.0), 50.0)
    right = stream_stats(_stream(50.0), 50.0)
    assert slow is not None and right is not None
    assert rate_excess_ms(right, 0.05) == 0.0 and jitter_excess_ms(right, 0.5) == 0.0
    assert rate_excess_ms(slow, 0.05) > 100.0  # 3 s at 45 Hz is ~150 ms longer than 47.5 Hz allows
    bursty = stream_stats([t + 0.1 * (i // 15) for i, t in enumerate(_stream(50.0))], 50.0)  # a 100 ms gap in 15
    assert bursty is not None and 80.0 < jitter_excess_ms(bursty, 0.5) < 100.0


def test_the_psi_total_is_read_from_the_some_line_only() -> None:
    from conformance.harness.starvation import parse_psi_total

    assert parse_psi_total("some avg10=8.10 avg60=19.45 avg300=22.75 total=4994318517\n") == 4994318517
    assert parse_psi_total("full avg10=0.00 avg60=0.00 avg300=0.00 total=7") is None
    assert parse_psi_total("some avg10=1.00 total=x") is None


def test_only_a_loopback_peer_shares_the_suites_cpu() -> None:
    from conformance.harness.starvation import is_loopback

    assert is_loopback("127.0.0.1") and is_loopback("127.3.2.1") and is_loopback("::1")
    assert is_loopback("[::1]") and is_loopback("::ffff:127.0.0.1") and is_loopback("localhost")
    assert not is_loopback("10.0.0.2") and not is_loopback("192.168.1.9") and not is_loopback("robot.plant")


def test_the_host_stall_is_the_psi_growth_between_the_samples_around_a_stretch() -> None:
    gauge = StarvationGauge()
    for i, total in enumerate((0, 10_000, 60_000, 60_500)):  # µs: 10 ms, 50 ms, 0.5 ms of CPU waits
        gauge.note_pressure(100.0 + i * 0.05, 1000.0 + i * 0.05, total)
    assert gauge.host_stall_ms(100.05, 100.10) == 50.0
    assert gauge.host_stall_ms(1000.0, 1000.15, wall=True) == 60.5
    assert gauge.host_stall_ms(99.0, 100.1) == 0.0  # no sample before the stretch: no evidence
    assert gauge.host_stall_ms(100.1, 101.0) == 0.0  # none after it either


def test_a_write_of_several_requests_is_counted_frame_by_frame() -> None:
    from conformance.protocol import Action, encode, request, whole_frames

    none, pose = encode(request(Action.NONE)), encode(request(Action.POSE))
    assert whole_frames(none) == 1
    assert whole_frames(none + pose + none) == 3
    assert whole_frames(none + pose[:7]) == 1  # a frame cut short is not counted
    assert whole_frames(b"garbage" + none) == 0  # nor anything after bytes that start no frame


def test_the_answer_to_a_later_frame_of_one_write_is_its_own_place() -> None:
    from conformance.harness.waits import COALESCED, STREAM_CUT_S

    ran_out = RanOut()
    for case_id in ("R4-01", "A1-01")[:REPEAT]:
        ran_out.ran_out(case_id, COALESCED)
        ran_out.case_ended(case_id, failed_on_silence=True)
    assert ran_out.bound(COALESCED, 5.0) == STREAM_CUT_S  # a later frame's answer may trail the first a little
    assert ran_out.bound(3, 5.0) is None  # the plain places are not touched
    ran_out.answered_at(COALESCED)
    assert ran_out.bound(COALESCED, 5.0) is None


def test_a_probe_swallowed_by_a_legal_framing_is_not_wronged() -> None:
    """64 KiB of FE read 12 bytes at a time (R6 (b), resume at the 12th byte) swallows the NONE behind them:
    the refusals of the rejected headers (00 FFFF) and no 0000 after them are legal, so the refused pattern's
    A1 FAIL does not apply (an independent Node.js box, legal-c, was FAILed on R2-01[64k-of-fe] for it)."""
    from conformance.harness.quiet import probe_wronged
    from conformance.protocol import DEFAULT_PROFILE, Action, encode, request
    from conformance.protocol.answers import Seen
    from conformance.protocol.explain import explain
    from conformance.protocol.framings import End

    none = encode(request(Action.NONE))
    swallowed = explain(b"\xfe" * 65536 + none, [Seen(0, 0xFFFF)], End.SILENT, DEFAULT_PROFILE, probe_at=65536)
    assert not probe_wronged(swallowed)
    reached = explain(b"hello" + none, [Seen(0, 0xFFFF)], End.SILENT, DEFAULT_PROFILE, probe_at=5)
    assert probe_wronged(reached)  # every framing reaches the NONE behind 5 bytes of garbage: it must get 0000


def test_bytes_that_are_whole_frames_by_their_headers() -> None:
    from conformance.harness.quiet import whole_frames
    from conformance.protocol import Header, Profile, encode_raw

    profile = Profile()
    one = encode_raw(Header(action=1, transfer_type=0), profile=profile)  # a frame that is not a request, whole
    assert whole_frames(one, profile) and whole_frames(one + one, profile)
    assert not whole_frames(one[:-1], profile)  # an incomplete frame
    assert not whole_frames(one + b"\x00", profile)  # a trailing byte
    assert not whole_frames(b"\x00" * 14, profile) and not whole_frames(b"", profile)  # garbage, nothing


def test_probes_lost_after_whole_frames_are_one_pattern_however_the_box_phrases_it() -> None:
    """d19's kind (R4): the probe behind whole frames goes unanswered, whether the box answered the frames (a
    refusal) or not (a frame that is not a request): two such cases establish one pattern for both, and a probe
    answered behind garbage (not whole frames) does not withdraw it."""
    from conformance.harness.quiet import AFTER_FRAMES, pattern_keys

    hangs = Hangs()
    for n, (kind, answered) in enumerate([("reject", True), ("not-request", False)]):
        for key in pattern_keys(kind, answered, whole=True):
            hangs.note(key, f"case-{n}", hung=True, probe_answered=False)
    for key in pattern_keys("not-request", False, whole=False):  # garbage: the probe was answered
        hangs.note(key, "garbage", hung=False, probe_answered=True)
    assert hangs.known(AFTER_FRAMES) == ["case-0", "case-1"]
    assert hangs.bound("not-request", False, 5.0, whole=True) == CUT_S
    assert hangs.bound("not-request", False, 5.0, whole=False) is None  # garbage is another pattern
    assert hangs.known_any(pattern_keys("any", True, whole=True)) == (AFTER_FRAMES, ["case-0", "case-1"])
    hangs.note(AFTER_FRAMES, "answered", hung=False, probe_answered=True)  # a probe behind whole frames answered
    assert hangs.bound("any", False, 5.0, whole=True) is None


def test_the_short_wait_follows_the_boxs_own_pace() -> None:
    from conformance.harness.quiet import CUT_MIN_S, PACE_FACTOR

    hangs = Hangs()
    assert hangs.cut_s(5.0) == CUT_S  # nothing measured yet
    for latency in (0.001, 0.015):
        hangs.paced(latency)
    assert hangs.cut_s(5.0) == PACE_FACTOR * 0.015
    assert hangs.cut_s(0.05) == 0.05  # never over time_out
    hangs.paced(0.0001)
    assert hangs.cut_s(5.0) == PACE_FACTOR * 0.015  # the slowest of the recent answers
    slow = Hangs()
    for _ in range(3):
        slow.paced(0.2)
    assert slow.cut_s(5.0) == CUT_S  # a slow box keeps the full short wait
    quick = Hangs()
    for _ in range(3):
        quick.paced(0.0001)
    assert quick.cut_s(5.0) == CUT_MIN_S


def test_bytes_sent_in_pieces_are_their_own_places_by_where_the_first_piece_ends() -> None:
    """d02's kind (R3): a frame whose header came in pieces goes unanswered; learnt after two cases, and a
    frame split only after its header, answered, does not withdraw it."""
    from conformance.harness.waits import SPLIT_PLACES, STREAM_CUT_S

    ran_out = RanOut()
    header, body = SPLIT_PLACES["header"], SPLIT_PLACES["body"]
    assert header != body
    for n in range(REPEAT):
        ran_out.ran_out(f"R3-01[{n}]", header)
        ran_out.case_ended(f"R3-01[{n}]", failed_on_silence=True)
    ran_out.answered_at(body)
    assert ran_out.bound(header, 5.0) == STREAM_CUT_S and ran_out.bound(body, 5.0) is None
    ran_out.answered_at(header)
    assert ran_out.bound(header, 5.0) is None
