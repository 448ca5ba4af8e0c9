"""The diagnose phase's UDP family against boxes of tests/impls served in this process (sockets and threads, no
suite run): each box reads F6/F7/R7 one way other than PROTOCOL.md's, the phase is given the root cause the
catalogue gathers (kind ``udp`` or ``tcp-check``) and its title must name the mechanism planted; a conforming
box's root cause stays unconfirmed."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import pytest

from conformance.diagnose.phase import diagnose
from conformance.engine.rootcause import SessionFacts
from conformance.harness.target import Target
from conformance.model.verdicts import CaseResult, Level, RootCause, Verdict
from conformance.protocol import Profile
from tests.impls.boxcore import ThreadBox
from tests.impls.policy import Choices, random_choices

FAST = {"latency": "0", "cycle_on_latency": "0", "writer": "whole", "udp": "on", "stream_port": "same"}


@contextmanager
def serving(choices: Choices) -> Iterator[ThreadBox]:
    box = ThreadBox(choices).start()
    try:
        yield box
    finally:
        box.stop()


def diagnosed(choices: Choices, kind: str) -> RootCause:
    profile = Profile().replace(first_index=int(choices.first_index), time_out_ms=1500)
    member = CaseResult("F7-01", "F7-01", ("F7",), Level.MUST, Verdict.FAIL, "seen")
    cause = RootCause("RC1", ("F7",), "as the catalogue read it", "evidence", ["F7-01"], kind=kind)
    with serving(choices) as box:
        assert box.udp_port is not None
        done = diagnose([cause], [member], SessionFacts(), Target("127.0.0.1", box.port), profile, 1.5,
                        udp_target=Target("127.0.0.1", box.udp_port))
    assert done.elapsed_s <= 20 + 2
    return done.causes[0]


@pytest.mark.parametrize("defect, kind, mechanism, words", [
    ("udp-crc-ccitt", "udp", "udp-crc-algorithm", "Signs and checks UDP frames with CRC-16/CCITT-FALSE, not "
                                                  "CRC-16/MODBUS: rerun with `--crc crc-ccitt-false`"),
    ("udp-no-crc-check", "udp", "udp-crc-unchecked", "UDP CRC not checked"),
    ("udp-crc-header", "udp", "udp-crc-coverage", "over the 12-byte header only, not over the blocks"),
    ("udp-answer-port", "udp", "udp-answer-port", "to the request's source port +1"),
    ("udp-two-frames", "udp", "udp-several-frames", "Takes 2 frames from one datagram"),
    ("tcp-check-crc", "tcp-check", "tcp-check-field", "in the check field of its TCP answers (the CRC-16/MODBUS"),
    ("tcp-crc-refused", "tcp-check", "tcp-crc-refused", "Refuses a TCP request whose check field holds its CRC"),
])
def test_the_title_names_the_planted_mechanism(defect: str, kind: str, mechanism: str, words: str) -> None:
    cause = diagnosed(random_choices(7, fixed=FAST).with_defect(defect), kind)
    assert cause.confirmed is True and cause.diagnosis is not None, cause.title
    assert cause.diagnosis["mechanism"] == mechanism, cause.title
    assert words in cause.title, cause.title
    assert cause.diagnosis["experiments"][0]["exchanges"], "the bytes that showed it are kept"


@pytest.mark.parametrize("kind", ["udp", "tcp-check"])
def test_a_conforming_box_confirms_nothing(kind: str) -> None:
    cause = diagnosed(replace(random_choices(9, fixed=FAST), defect=None), kind)
    assert cause.confirmed is False and cause.title == "unconfirmed: as the catalogue read it"
