"""Which conversations are iSight and who is the robot (conformance/analyze/conversations.py)."""

from __future__ import annotations

from conformance.analyze.analysis_context import AnalyzeConfig, Context
from conformance.analyze.capture_packets import TCP, PacketDecoder
from conformance.analyze.conversations import Conversations
from conformance.analyze.sessions import SessionTracker
from conformance.protocol import Action, answer, encode, request
from tests.analyze_util import Capture, exchange

NONE, NONE_OK = encode(request(Action.NONE)), encode(answer(Action.NONE))


def run(cap: Capture, config: AnalyzeConfig | None = None) -> tuple[Context, list]:
    ctx = Context(config or AnalyzeConfig())
    convs = Conversations(ctx, SessionTracker(ctx))
    started = []
    original = convs._start

    def spy(key, robot_dir, packets, handshake):
        original(key, robot_dir, packets, handshake)
        started.append(convs.tcp[key][2])

    convs._start = spy  # type: ignore[method-assign]
    decode = PacketDecoder().decode
    for n, pkt in enumerate(cap.packets, 1):
        seg = decode(1, bytes(pkt))
        if seg and seg[0] == TCP:
            convs.tcp_packet(seg[1], *seg[2:], n, float(pkt.time))
        elif seg:
            convs.udp_packet(seg[1], seg[5], seg[6], n, float(pkt.time))
    convs.finish(cap.t, len(cap.packets))
    return ctx, started


def test_the_syn_tells_the_robot_even_on_the_box_side_port():
    cap = Capture()
    conn = cap.tcp(9004, box_port=41000)  # the robot's ephemeral port happens to be 9004
    exchange(conn, NONE, NONE_OK)
    conn.close()
    ctx, conns = run(cap, AnalyzeConfig(ports=(9004,)))
    assert conns[0].robot == ("10.0.0.2", 9004) and conns[0].handshake


def test_without_a_handshake_the_side_on_the_port_is_the_box():
    cap = Capture()
    conn = cap.tcp(41000, handshake=False)
    exchange(conn, NONE, NONE_OK)
    ctx, conns = run(cap)
    assert conns[0].box == ("10.0.0.1", 9004) and not conns[0].handshake
    assert ctx.stats.midstart == 1


def test_on_another_port_the_transfer_type_tells_the_robot_even_if_the_box_speaks_first():
    cap = Capture()
    conn = cap.tcp(41000, box_port=7000, handshake=False)
    conn.box(NONE_OK)
    conn.robot(NONE)
    ctx, conns = run(cap)
    assert len(conns) == 1 and conns[0].robot == ("10.0.0.2", 41000)


def test_traffic_that_never_shows_an_isight_header_is_ignored():
    cap = Capture()
    for i in range(12):
        cap.other(b"SSH-2.0-OpenSSH_9.6\r\n" * (i + 1), port=22)
    ctx, conns = run(cap)
    assert conns == [] and ctx.stats.tcp_connections == 0


def test_packets_seen_before_the_first_isight_header_are_replayed_into_the_connection():
    cap = Capture()
    conn = cap.tcp(41000, box_port=7000)  # a handshake on an unknown port, then iSight
    exchange(conn, NONE, NONE_OK)
    conn.close()
    ctx, conns = run(cap)
    assert len(conns) == 1 and conns[0].handshake and conns[0].stream.client == conns[0].robot_dir
    assert ctx.findings.tallies[("A4", "box")].checked == 1


def test_a_new_syn_on_the_same_ports_is_a_new_connection():
    cap = Capture()
    for _ in range(2):
        conn = cap.tcp(41000, robot_seq=1000 + len(cap.packets) * 1000)
        exchange(conn, NONE, NONE_OK)
        conn.close()
    ctx, conns = run(cap)
    assert len(conns) == 2 and ctx.stats.sessions == 2
    assert ctx.findings.tallies[("A4", "box")].checked == 2


def test_udp_on_the_port_is_followed_and_other_udp_is_not():
    cap = Capture()
    cap.udp(b"\x00" * 20, robot_port=5353, box_port=5353)
    cap.udp(encode(request(Action.NONE)), robot_port=40000, box_port=9004)
    ctx, _ = run(cap)
    assert ctx.stats.udp_conversations == 1
