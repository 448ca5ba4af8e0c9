"""iSight over UDP (conformance/analyze/udp_conversation.py): one datagram one frame, the CRC, R7."""

from __future__ import annotations

from conformance.analyze.analysis_context import AnalyzeConfig, Context
from conformance.analyze.capture_packets import PacketDecoder
from conformance.analyze.udp_conversation import UdpConversation, crc_reading
from conformance.model.verdicts import Verdict
from conformance.protocol import Action, Profile, answer, encode_udp, request
from tests.analyze_util import Capture


def conversation(config: AnalyzeConfig) -> tuple[Context, UdpConversation, bytes]:
    ctx = Context(config)
    cap = Capture()
    pkt = cap.udp(b"x")
    key = PacketDecoder().decode(1, bytes(pkt))[1]
    return ctx, UdpConversation(ctx, key, 0), key


def test_crc_reading_names_the_algorithm_the_check_fits():
    other = encode_udp(request(Action.NONE), Profile(crc="xmodem", crc_byte_order="little"))
    assert crc_reading(other, Profile()) == ("xmodem", "little")
    assert crc_reading(encode_udp(request(Action.NONE)), Profile()) is None  # the profile's own CRC
    assert crc_reading(b"\xfe\xfe\x00\x01\x01\x00" + bytes(8), Profile()) is None


def test_requests_and_answers_pair_and_a_duplicate_counts_once():
    ctx, conv, _key = conversation(AnalyzeConfig())
    req, ans = encode_udp(request(Action.NONE)), encode_udp(answer(Action.NONE))
    conv.datagram(0, req, 0, 1, 1.0)
    conv.datagram(0, req, 0, 2, 1.0002)  # a mirror port's copy
    conv.datagram(1, ans, 0, 3, 1.001)
    conv.finish(2.0)
    t = ctx.findings.tallies
    assert t[("A1", "box")].checked == 1 and not t[("A1", "box")].counts
    assert t[("F7", "robot")].checked == 1 and t[("F7", "box")].checked == 1
    assert conv.label.startswith("udp ")


def test_a_bad_datagram_answered_with_an_error_is_non_strict_and_unanswered_passes():
    ctx, conv, _key = conversation(AnalyzeConfig(crc_stated=True))
    bad = encode_udp(request(Action.NONE))[:-1]  # not one whole frame
    conv.datagram(0, bad, 0, 1, 1.0)
    conv.datagram(1, encode_udp(answer(Action.NONE, 0x1001)), 0, 2, 1.001)
    conv.datagram(0, bad + b"\x00\x00", 0, 3, 1.1)
    conv.finish(2.0)
    t = ctx.findings.tallies[("R7", "box")]
    assert t.counts == {Verdict.NON_STRICT: 1} and t.checked == 1
    assert ctx.findings.tallies[("F5", "robot")].counts == {Verdict.FAIL: 2}


def test_a_datagram_cut_by_the_snap_length_is_not_judged():
    ctx, conv, _key = conversation(AnalyzeConfig())
    conv.datagram(0, encode_udp(request(Action.NONE))[:8], 6, 1, 1.0)
    conv.finish(2.0)
    assert "snap length" in ctx.findings.tallies[("F7", "robot")].notes[0]
    assert not ctx.findings.tallies[("F7", "robot")].counts
