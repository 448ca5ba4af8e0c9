"""conformance/harness/connection.py: one way to a box for the cases, the fuzzer and the diagnose experiments:
a Dialer dials recorded connections, and a connection receives with a deadline (never an exception)."""

from __future__ import annotations

import socket
import time

import pytest

from conformance.harness.client import Answer, Silence
from conformance.harness.connection import Dialer
from conformance.harness.target import Target, Unreachable
from conformance.harness.transcript import Kind, Transcript
from conformance.protocol import Action, Profile, request
from tests.boxes import ScriptedBox, answering, silent

pytestmark = pytest.mark.timeout(30)
P = Profile(time_out_ms=2000)


def test_dial_send_and_receive_by_a_deadline() -> None:
    with ScriptedBox(answering()) as box:
        dialer = Dialer(Transcript("T"), Target("127.0.0.1", box.port), P)
        conn = dialer.dial("command")
        conn.send(request(Action.NONE), "NONE")
        outcome = conn.receive(dialer.by())
        conn.close()
    assert isinstance(outcome, Answer) and outcome.frame.action is Action.NONE
    assert conn.time_out_s == P.time_out_s and dialer.time_out_s == P.time_out_s
    kinds = [e.kind for e in dialer.transcript.events]
    assert Kind.CONNECT in kinds and Kind.SEND in kinds and Kind.RECV in kinds  # every byte recorded


def test_a_deadline_already_passed_is_silence_at_once() -> None:
    with ScriptedBox(silent) as box:
        conn = Dialer(Transcript("T"), Target("127.0.0.1", box.port), P).dial("command")
        conn.send(request(Action.NONE), "NONE")
        outcome = conn.receive(time.monotonic() - 1.0)
        conn.close()
    assert isinstance(outcome, Silence)


def test_the_deadline_cuts_every_wait() -> None:
    deadline = time.monotonic() + 0.5
    dialer = Dialer(Transcript("T"), Target("127.0.0.1", 9), P, time_out_s=5.0, deadline=deadline)
    assert dialer.wait_s() <= 0.5 and dialer.by() <= deadline
    assert Dialer(Transcript("T"), Target("127.0.0.1", 9), P).wait_s() == P.time_out_s  # no deadline: time_out


def test_an_unreachable_box_raises_from_dial_only() -> None:
    with socket.socket() as bound:  # bound, never listening: the port stays ours and refuses
        bound.bind(("127.0.0.1", 0))
        with pytest.raises(Unreachable):
            Dialer(Transcript("T"), Target("127.0.0.1", bound.getsockname()[1]), P).dial("command")
