"""analyze on a capture recorded from a live little-endian session (a box and a robot on loopback); the
command on synthetic captures is tested in tests/unit/test_analyze_cli.py."""

from __future__ import annotations

import json

from conformance.endpoints.behaviour import BoxConfig
from tests.analyze_util import FAST, record
from tests.unit.test_analyze_cli import run


def test_a_little_endian_lenient_read_takes_every_field_in_the_profiles_byte_order(capsys, tmp_path):
    """A box and a robot that both write little-endian headers and floats, read with
    ``--byte-order little --float-byte-order little --checking lenient``: every frame decodes
    (no F2/F4/F5 finding), the box conforms; read with the default profile the same capture is
    all the wrong way round (the flags are what made the difference). About 2 s."""
    little = FAST.replace(byte_order="little", float_byte_order="little", strict=False)
    path, _ = record(tmp_path / "little.pcapng", box=BoxConfig(profile=little), profile=little)
    code, out, err = run(capsys, path, "--report-dir", tmp_path / "r", "--byte-order", "little",
                         "--float-byte-order", "little", "--checking", "lenient", "--time-out", "1000",
                         "--vision-time-out", "1000", "--rate-tolerance", "50", "--jitter-tolerance", "300")
    doc = json.loads((tmp_path / "r" / "summary.json").read_text())
    cases = {c["id"]: c for c in doc["cases"]}
    assert code == 0, err
    assert doc["suite"]["profile"]["byte_order"] == "little" and doc["suite"]["profile"]["strict"] is False
    for case in ("OBS-F2-box", "OBS-F5-box", "OBS-A2-box", "OBS-F2-robot", "OBS-F4-robot", "OBS-F5-robot", "OBS-B1-robot"):
        assert cases[case]["verdict"] == "PASS", cases[case]
    assert cases["OBS-F4-box"]["verdict"] in ("PASS", "SKIP")  # the box's answers carry no values here
    code, _out, err = run(capsys, path, "--report-dir", tmp_path / "big")
    assert code == 1 and "OBS-F2" in err
