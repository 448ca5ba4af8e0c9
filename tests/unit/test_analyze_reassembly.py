"""TCP reassembly (conformance/analyze/reassembly.py): each direction's bytes once and in
order; retransmissions dropped (and compared); out-of-order segments waiting; gaps found
from the other side's ACKs; an answer never delivered before the request it answers."""

from __future__ import annotations

from conformance.analyze.capture_packets import ACK, FIN, PSH, RST, SYN
from conformance.analyze.reassembly import DONE, REORDER_PACKETS, RESTART, STALL_PACKETS, TcpStream

PA = PSH | ACK


class Sink:
    def __init__(self) -> None:
        self.events: list[tuple] = []
        self.stream = TcpStream(self, [lambda p, n, t: self.events.append(("data", 0, bytes(p), n)),
                                       lambda p, n, t: self.events.append(("data", 1, bytes(p), n))])

    def gap(self, d, nbytes, before, after, ts):
        self.events.append(("gap", d, nbytes, before, after))

    def snap(self, d, nbytes, no, ts):
        self.events.append(("snap", d, nbytes, no))

    def close(self, d, how, no, ts):
        self.events.append(("close", d, how, no))

    def conflict(self, d, no, ts):
        self.events.append(("conflict", d, no))

    def midstart(self, d):
        self.events.append(("midstart", d))

    def data(self, d):
        return b"".join(e[2] for e in self.events if e[0] == "data" and e[1] == d)


def handshake(s: Sink) -> int:
    seg = s.stream.segment
    seg(0, 100, 0, SYN, b"", 0, 1, 0.0)
    seg(1, 500, 101, SYN | ACK, b"", 0, 2, 0.0)
    seg(0, 101, 501, ACK, b"", 0, 3, 0.0)
    return 4


def test_in_order_bytes_both_ways_and_the_close():
    s = Sink()
    handshake(s)
    seg = s.stream.segment
    assert seg(0, 101, 501, PA, b"abc", 0, 4, 1.0) is None
    assert seg(1, 501, 104, PA, b"XY", 0, 5, 1.0) is None
    assert seg(0, 104, 503, FIN | ACK, b"", 0, 6, 2.0) is None
    assert seg(1, 503, 105, FIN | ACK, b"", 0, 7, 2.0) == DONE
    assert s.events == [("data", 0, b"abc", 4), ("data", 1, b"XY", 5), ("close", 0, "fin", 6), ("close", 1, "fin", 7)]
    assert s.stream.client == 0


def test_retransmissions_are_dropped_and_compared():
    s = Sink()
    handshake(s)
    seg = s.stream.segment
    seg(0, 101, 501, PA, b"abcdef", 0, 4, 1.0)
    seg(0, 101, 501, PA, b"abcdef", 0, 5, 1.1)  # the same bytes again
    seg(0, 104, 501, PA, b"defgh", 0, 6, 1.2)  # overlaps: only "gh" is new
    assert s.data(0) == b"abcdefgh"
    assert not [e for e in s.events if e[0] == "conflict"]
    seg(0, 102, 501, PA, b"ZZ", 0, 7, 1.3)  # claims other bytes where "bc" went
    assert ("conflict", 0, 7) in s.events
    assert s.data(0) == b"abcdefgh"


def test_out_of_order_segments_wait_for_the_bytes_before_them():
    s = Sink()
    handshake(s)
    seg = s.stream.segment
    seg(0, 104, 501, PA, b"def", 0, 5, 1.0)
    assert s.data(0) == b""
    seg(0, 101, 501, PA, b"abc", 0, 4, 1.0)
    assert s.data(0) == b"abcdef"
    assert [e[3] for e in s.events if e[0] == "data"] == [4, 5]


def test_an_answer_shown_before_its_request_is_held_back():
    s = Sink()
    handshake(s)
    seg = s.stream.segment
    seg(1, 501, 104, PA, b"ANS", 0, 5, 1.001)  # acknowledges 3 robot bytes not seen yet
    assert s.events == []
    seg(0, 101, 501, PA, b"req", 0, 4, 1.0)
    assert [e[:3] for e in s.events] == [("data", 0, b"req"), ("data", 1, b"ANS")]


def test_bytes_acknowledged_but_never_seen_become_a_gap():
    s = Sink()
    handshake(s)
    seg = s.stream.segment
    seg(0, 101, 501, PA, b"aaa", 0, 4, 1.0)
    # the segment 104..107 is missing from the capture; the box acknowledges it and answers
    seg(1, 501, 107, PA, b"A1", 0, 6, 1.1)
    seg(0, 107, 503, PA, b"ccc", 0, 7, 1.2)
    assert s.data(0) == b"aaa" and s.data(1) == b""  # waiting: the capture may show it late
    n = 8
    for _ in range(REORDER_PACKETS):
        seg(1, 503, 107, ACK, b"", 0, n, 1.3)
        n += 1
    # 3 bytes missing between frame 4 and frame 7 (where the robot's bytes resume); the answer
    # (frame 6) follows the gap, and the robot's next bytes follow the answer they acknowledge
    assert s.events[1:] == [("gap", 0, 3, 4, 7), ("data", 1, b"A1", 6), ("data", 0, b"ccc", 7)]


def test_a_hole_without_ack_evidence_is_a_gap_after_a_long_stall():
    s = Sink()
    handshake(s)
    seg = s.stream.segment
    seg(0, 110, 501, PA, b"later", 0, 4, 1.0)
    for n in range(STALL_PACKETS):
        seg(1, 501, 101, ACK, b"", 0, 5 + n, 1.0)
    assert ("gap", 0, 9, 1, 4) in s.events  # after the SYN (frame 1), before frame 4
    assert s.data(0) == b"later"


def test_a_snapped_segment_hands_on_the_bytes_not_kept_as_a_count_at_once():
    """Bytes cut by the snap length are a known count at a known place (``snap``), not a gap."""
    s = Sink()
    handshake(s)
    s.stream.segment(0, 101, 501, PA, b"ab", 5, 4, 1.0)
    s.stream.segment(0, 108, 501, PA, b"cd", 0, 5, 1.0)
    assert s.events == [("data", 0, b"ab", 4), ("snap", 0, 5, 4), ("data", 0, b"cd", 5)]


def test_the_end_of_the_capture_flushes_what_waits():
    s = Sink()
    handshake(s)
    s.stream.segment(0, 104, 501, PA, b"def", 0, 4, 1.0)
    s.stream.finish(2.0)
    assert s.events == [("gap", 0, 3, 1, 4), ("data", 0, b"def", 4)]


def test_a_connection_seen_mid_way_starts_where_the_capture_does():
    s = Sink()
    s.stream.segment(0, 9000, 100, PA, b"xyz", 0, 1, 1.0)
    s.stream.segment(1, 100, 9003, PA, b"ok", 0, 2, 1.0)
    assert s.events == [("midstart", 0), ("data", 0, b"xyz", 1), ("midstart", 1), ("data", 1, b"ok", 2)]
    assert s.stream.client is None


def test_a_reset_ends_it_and_a_new_syn_restarts():
    s = Sink()
    handshake(s)
    assert s.stream.segment(1, 501, 101, RST | ACK, b"", 0, 4, 1.0) == DONE
    assert s.events == [("close", 1, "rst", 4)] and s.stream.reset_by == 1
    assert s.stream.segment(0, 101, 501, ACK, b"x", 0, 5, 1.0) == DONE and s.data(0) == b""
    assert s.stream.segment(0, 7777, 0, SYN, b"", 0, 6, 2.0) == RESTART


def test_sequence_numbers_wrap():
    s = Sink()
    seg = s.stream.segment
    seg(0, 0xFFFFFFFE, 0, SYN, b"", 0, 1, 0.0)
    seg(1, 10, 0xFFFFFFFF, SYN | ACK, b"", 0, 2, 0.0)
    seg(0, 0xFFFFFFFF, 11, PA, b"ab", 0, 3, 0.0)
    seg(0, 1, 11, PA, b"cd", 0, 4, 0.0)
    seg(1, 11, 3, PA, b"Z", 0, 5, 0.0)
    assert s.data(0) == b"abcd" and s.data(1) == b"Z"
    assert not [e for e in s.events if e[0] == "gap"]
