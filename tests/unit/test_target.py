"""conformance.harness.target: HOST:PORT parsing."""

from __future__ import annotations

import pytest

from conformance.harness.target import Target


@pytest.mark.parametrize(
    ("text", "host", "port"),
    [("10.0.0.5:9000", "10.0.0.5", 9000), ("[::1]:9004", "::1", 9004), ("localhost:1", "localhost", 1), (" box:65535 ", "box", 65535)],
)
def test_parse(text: str, host: str, port: int) -> None:
    assert Target.parse(text) == Target(host, port)


def test_default_port_and_printing() -> None:
    assert Target.parse("192.168.0.200", default_port=9004) == Target("192.168.0.200", 9004)
    assert str(Target("::1", 9004)) == "[::1]:9004"
    assert str(Target("box", 1)) == "box:1"


@pytest.mark.parametrize(
    ("text", "message"),
    [("", "empty"), ("box:x", "not a number"), ("box:0", "out of range"), ("box:70000", "out of range"),
     ("::1:9004", "IPv6"), ("[::1:9004", "missing"), (":9004", "no host"), ("box", "expected HOST:PORT"),
     ("box:", "no port"), ("[::1]:", "no port"), ("[::1]x", "IPv6")],
)
def test_bad_targets_say_why(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Target.parse(text)
