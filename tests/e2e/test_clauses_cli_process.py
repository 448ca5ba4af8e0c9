"""The clauses command as an installed process: exit 2 on an unknown clause, no traceback when the reader
has left; the command in-process is tested in tests/unit/test_clauses_cli.py."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


def test_the_installed_command_exits_2_on_an_unknown_clause():
    proc = subprocess.run([sys.executable, "-m", "conformance", "clauses", "Q1"], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().startswith("isight-conformance clauses: unknown clause 'Q1'")


@pytest.mark.parametrize("argv", [["clauses"], ["run", "--list"]])
def test_a_reader_that_has_left_is_no_traceback(argv):
    """``isight-conformance clauses | head -1``: a closed pipe ends the command quietly."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first line: every write meets EPIPE
    try:
        proc = subprocess.run([sys.executable, "-m", "conformance", *argv], stdout=write_end,
                              stderr=subprocess.PIPE, timeout=60, check=False)
    finally:
        os.close(write_end)
    err = proc.stderr.decode()
    assert proc.returncode == 0 and "Traceback" not in err and "BrokenPipe" not in err
