"""Importing the scapy layer in a fresh interpreter is quiet and binds only port 9004; the layer itself is
tested in tests/unit/test_scapy_layer.py."""

from __future__ import annotations

import subprocess
import sys

from tests.unit.test_scapy_layer import ROOT


def test_import_is_quiet_and_binds_only_9004() -> None:
    code = (
        "import conformance.evidence.scapy_layer as m\n"
        "from scapy.layers.inet import TCP, UDP\n"
        "print(sorted({(l.__name__, k, v) for l in (TCP, UDP) for f, c in l.payload_guess"
        " if c is m.ISight for k, v in f.items()}))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stderr == ""
    assert out.stdout.strip() == (
        "[('TCP', 'dport', 9004), ('TCP', 'sport', 9004), ('UDP', 'dport', 9004), ('UDP', 'sport', 9004)]"
    )
