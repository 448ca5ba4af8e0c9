"""R: robustness (garbage, split and coalesced delivery, bounded resources, resynchronisation).

R1 is covered by the vector replay and R7 (UDP) by the UDP cases.
"""

from __future__ import annotations

import random
import time

import pytest

from conformance.protocol import Action, Frame, Header, encode_raw, request
from conformance.protocol.constants import START_BYTES
from conformance.suite import (
    CLOSED,
    DEFAULT_POSE,
    NOT_ANSWERED,
    NOT_OK,
    Answer,
    CaseContext,
    Closed,
    Expect,
    Level,
    Requirement,
    TcpConnection,
    answered,
    answered_allowed,
    case,
    latency_figures,
    pieces_of,
)

# -- the family's helpers: Helpers of the R2-R6 cases (conformance/cases/robustness.py): garbage, held connections, the whole frame as a reference, resynchronisation.
#: R2: a fresh connection after the input gets NONE answered 0000
ALIVE = Requirement(("R2",), "whatever bytes one connection sends, the box keeps accepting and answering new connections "
                    "(after {after})", accept=answered_allowed(Action.NONE))


def valid_frames(isight: CaseContext) -> dict[str, Frame]:
    return {
        "none": request(Action.NONE),
        "pose": request(Action.POSE, isight.codec.pose_blocks([DEFAULT_POSE])),
        "tolerance": request(Action.TOLERANCE, isight.codec.tolerance_blocks([1.5, 2.5])),
        "register-pose": request(Action.REGISTER_POSE, isight.codec.pose_blocks([DEFAULT_POSE, (1, 2, 3, 4, 5, 6)])),
    }


def assert_alive(isight: CaseContext, after: str) -> None:
    isight.judge(isight.check_alive(), "alive", after=after)


def no_fe(data: bytes) -> bytes:
    return data.replace(b"\xfe", b"\x00")


GARBAGE = {
    "random-bytes": no_fe(random.Random(2024).randbytes(4096)),
    "64k-of-fe": b"\xfe" * 65536,
}

#: R3: the reference answer to the whole frame, to compare a split delivery with
WHOLE = Requirement(("R3",), "the whole {frame.action.name} request is answered, as a reference", inconclusive=NOT_ANSWERED,
                    inconclusive_text="the whole {frame.action.name} request was not answered: nothing to compare the "
                                      "split delivery with")

#: R3: a split delivery is answered like the whole frame
LIKE_WHOLE = lambda action, code, **_: answered(action, [code])  # noqa: E731


def like_whole(isight: CaseContext, frame: Frame) -> Answer:
    outcome = isight.exchange(frame, f"{frame.action.name} request, whole (reference)")
    isight.judge(outcome, "whole", frame=frame)
    assert isinstance(outcome, Answer)
    return outcome


def hold_connections(isight: CaseContext, label: str, count: int, data: bytes, deadline: float) -> list[TcpConnection]:
    """Open up to ``count`` connections (each sends ``data``); stop at the first refusal or the deadline."""
    out = []
    for i in range(count):
        left = deadline - time.monotonic()
        if left <= 0:
            break
        conn = isight.try_connect(f"{label} {i + 1}", time_out_s=min(isight.time_out_s, left))
        if conn is None:
            break
        if data:
            conn.send(data, f"{label}: {len(data)} bytes, then nothing")
        out.append(conn)
    return out


def fresh_answered(isight: CaseContext, when: str) -> None:
    """A fresh connection gets NONE and a pose answered 0000 within time_out. A box may make room by
    evicting a stale connection: a fresh connection it resets is retried until time_out has passed."""
    deadline = time.monotonic() + isight.time_out_s
    attempts = 0
    while True:
        attempts += 1
        left = deadline - time.monotonic()
        conn = isight.try_connect(f"fresh ({when}, attempt {attempts})", time_out_s=max(0.05, left))
        if conn is None:
            raise isight.broken(expected="a fresh connection is accepted within time_out",
                                observed=f"connection attempt {attempts} was not accepted", when=when)
        outcome = conn.request(request(Action.NONE), f"NONE on a fresh connection ({when})", timeout_s=max(0.05, left))
        if isinstance(outcome, Closed) and time.monotonic() + 0.1 < deadline:
            conn.close()
            time.sleep(0.1)
            continue
        break
    isight.details.setdefault("fresh_attempts", {})[when] = attempts
    for frame in (None, valid_frames(isight)["pose"]):
        if frame is not None:
            outcome = conn.request(frame, f"POSE on a fresh connection ({when})")
        action = Action.NONE if frame is None else frame.action
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)
        isight.judge(outcome, sent=conn.codec.encode(frame or request(Action.NONE)), action=action, when=when)
    conn.close()


RESYNC_GARBAGE = {
    "ascii": b"hello iSight\r\n",
    "zeros": b"\x00" * 32,
    "bad-start-word": b"\xfe\xff\x00\x01\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00",
    "bad-version": START_BYTES + b"\x00\x02\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00",
}


def resynced(action: Action, **_: object) -> Expect:
    return answered_allowed(action) | CLOSED


# -- the cases

# -- R2 ---------------------------------------------------------------------------------------------------


@case("R2-01", ["R2", "A5"], Level.MUST, "After garbage, new connections are still accepted and answered",
      "the garbage is not answered 0000, and a fresh connection gets NONE answered 0000",
      checks={"": Requirement(("A5",), "bytes that are not a request MUST NOT be answered 0000", accept=NOT_OK),
              "alive": ALIVE}, shares_box=True)
@pytest.mark.parametrize("kind", list(GARBAGE))
def test_garbage_then_fresh_connection(isight: CaseContext, kind: str) -> None:
    bad = GARBAGE[kind]
    isight.judge(isight.send_malformed(bad, f"{kind}: {len(bad)} bytes that are not a frame"), sent=bad[:64])
    assert_alive(isight, kind)


@case("R2-02", ["R2"], Level.MUST, "A header then a reset leaves the box answering new connections",
      "after a connection sends a pose header (12 bytes) and resets, a fresh connection gets NONE answered 0000",
      checks={"alive": ALIVE}, shares_box=True)
def test_header_then_reset(isight: CaseContext) -> None:
    conn = isight.connect("abuser")
    header = conn.codec.encode(valid_frames(isight)["pose"])[:12]
    isight.last_sent = header
    conn.send(header, "a pose header, no body")
    conn.abort("reset with the frame unfinished")
    assert_alive(isight, "a header then RST")


# -- R3 / R4 ----------------------------------------------------------------------------------------------


@case("R3-01", ["R3", "A1"], Level.MUST, "A frame sent one byte per segment is answered like the whole frame",
      "the same action and error code as for the whole frame, within time_out",
      checks={"whole": WHOLE, "": Requirement(("R3",), "a frame split down to one byte per segment is handled like the whole "
                                              "frame", accept=LIKE_WHOLE)}, shares_box=True)
@pytest.mark.parametrize("name", ["none", "pose", "tolerance"])
def test_one_byte_segments(isight: CaseContext, name: str) -> None:
    frame = valid_frames(isight)[name]
    whole = like_whole(isight, frame)
    conn = isight.connect()
    data = conn.codec.encode(frame)
    start = time.monotonic()
    conn.send_pieces(pieces_of(data, {"pieces": "bytes"}), 0.001, "one byte per segment")
    isight.judge(conn.next_outcome(since=start), sent=data, action=frame.action, code=whole.frame.error_code)


@case("R3-02", ["R3", "A1"], Level.MUST, "Frames cut at random points over time are each answered like whole frames",
      "four requests sent as one byte stream cut into random 1-8 byte pieces (2 ms apart) get four answers in order, "
      "each like the whole request's",
      checks={"whole": WHOLE, "": Requirement(("R3",), "request {n} of a randomly split stream is answered like the whole",
                                              accept=LIKE_WHOLE)}, shares_box=True)
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_splits(isight: CaseContext, seed: int) -> None:
    frames = list(valid_frames(isight).values())
    expected = [like_whole(isight, f).frame.error_code for f in frames]
    conn = isight.connect()
    data = b"".join(conn.codec.encode(f) for f in frames)
    isight.last_sent = data
    start = time.monotonic()
    conn.send_pieces(pieces_of(data, {"pieces": "random", "seed": seed}), 0.002, f"random split (seed {seed})")
    for i, (frame, code) in enumerate(zip(frames, expected)):
        isight.judge(conn.next_outcome(since=start), sent=data, n=i + 1, action=frame.action, code=code)


@case("R4-01", ["R4", "A1"], Level.MUST, "Ten frames in one segment are each answered, in order",
      "ten answers, echoing each request's action in order, each 0000",
      checks={"": Requirement(("R4",), "request {n} of 10 in one segment is answered, in order",
                              accept=lambda action, **_: answered_allowed(action))})
def test_coalesced(isight: CaseContext) -> None:
    frames = list(valid_frames(isight).values())
    batch = [frames[i % len(frames)] for i in range(10)]
    conn = isight.connect()
    data = b"".join(conn.codec.encode(f) for f in batch)
    isight.last_sent = data
    start = time.monotonic()
    conn.send(data, "10 requests in one segment")
    for i, frame in enumerate(batch):
        outcome = conn.next_outcome(since=start)
        if isinstance(outcome, Answer):
            isight.latencies_ms.append(outcome.latency_s * 1000)
        isight.judge(outcome, sent=data, n=i + 1, action=frame.action)


# -- R5 ---------------------------------------------------------------------------------------------------


@case("R5-01", ["R5", "T1"], Level.MUST, "Partial frames, a 255×65535 announcement and 300 idle connections "
      "do not stop the box answering others",
      "while 200 connections hold half a frame, one announces 255×65535 bytes and 300 are idle, a fresh connection "
      "gets NONE and a pose answered 0000 within time_out; again after they are released",
      checks={"": Requirement(("R5",), "partial frames, a 255×65535 header and idle connections do not stop the box "
                              "answering others ({when})", accept=lambda action, **_: answered_allowed(action))})
def test_bounded_resources(isight: CaseContext) -> None:
    deadline = time.monotonic() + 10 + 2 * isight.time_out_s
    pose = encode_raw(Header(action=Action.POSE, block_type=1, block_count=1, block_length=25))
    huge = encode_raw(Header(action=Action.POSE, block_type=1, block_count=255, block_length=65535))[:12]
    isight.last_sent = huge
    held = {
        "partial": hold_connections(isight, "partial frame", 200, pose[:19], deadline),
        "huge": hold_connections(isight, "255×65535 header", 1, huge, deadline),
        "idle": hold_connections(isight, "idle", 300, b"", deadline),
    }
    isight.details["opened"] = {k: len(v) for k, v in held.items()}
    fresh_answered(isight, "while they are held")
    for conns in held.values():
        for conn in conns:
            conn.close("release")
    fresh_answered(isight, "after they are released")
    isight.details["latency"] = latency_figures(isight.latencies_ms)


# -- R6 ---------------------------------------------------------------------------------------------------


@case("R6-01", ["R6"], Level.SHOULD, "After garbage the box resynchronises on the next valid frame, or closes",
      "the valid request right after the garbage, on the same connection, is answered 0000, or the connection is "
      "closed; staying silent is NON-STRICT",
      checks={"": Requirement(("R6",), "after garbage the box SHOULD resynchronise on the next valid header or close the "
                              "connection", accept=resynced)}, shares_box=True)
@pytest.mark.parametrize("kind", list(RESYNC_GARBAGE))
def test_resynchronise(isight: CaseContext, kind: str) -> None:
    bad = RESYNC_GARBAGE[kind]
    isight.send_malformed(bad, f"garbage ({kind}) then a valid request on the same connection")
    assert isight.last_probe is not None  # send_malformed always records what became of the probe
    isight.judge(isight.last_probe, action=isight.last_probe_action)
