"""Self-tests for the E, UDP (F7, R7) and discovery (PROFILE-01, F4) cases.

Each broken box is the reference box (:class:`BoxThread`) with one decision
monkeypatched on its loop, breaking one clause; the suite runs against it in a
subprocess (``--target``/``--udp-target``) and the case covering that clause must
end FAIL (MUST) or NON-STRICT (SHOULD), and nothing else must fail.

Results come from ``summary.json`` (``--report-dir``) when the report writer is
installed, else from this module loaded as a plugin in the subprocess
(``-p tests.e2e.test_cases_extension_udp``), whose ``pytest_sessionfinish`` dumps the
suite's case results as JSON.
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from conformance.endpoints.behaviour import BoxBehaviour, BoxConfig, Decision, Reaction
from conformance.endpoints.loop import BoxThread
from conformance.protocol import (
    Action,
    Frame,
    Profile,
    ProtocolError,
    TransferType,
    Transport,
    answer,
    value_blocks,
)

ROOT = Path(__file__).resolve().parents[2]
DUMP_ENV = "ISIGHT_SELFTEST_DUMP"
RUN_TIMEOUT_S = 90

Patch = Callable[[BoxBehaviour], None]


# -- the subprocess side: dump the case results (loaded with -p) -----------------------------


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session: pytest.Session) -> None:
    path = os.environ.get(DUMP_ENV)
    if not path:
        return
    from conformance.pytest_plugin import results

    cases = [dict(r.to_summary(), details=r.details) for r in results(session.config)]
    Path(path).write_text(json.dumps({"cases": cases}, default=str), encoding="utf-8")


# -- running the suite ---------------------------------------------------------------------------


def _has_report_writer() -> bool:
    try:
        module = importlib.import_module("conformance.report")
    except ImportError:
        return False
    return hasattr(module, "write_reports")


def run_suite(tmp_path: Path, cases: list[str], box: BoxThread | None = None, *extra: str) -> dict[str, dict[str, Any]]:
    """Run the selected cases in a subprocess; {case id: summary entry}."""
    args = [sys.executable, "-m", "pytest", "--pyargs", "conformance.cases", "-p", "no:cacheprovider", "-q",
            "--isight-capture", "off", *extra]
    for glob in cases:
        args += ["--cases", glob]
    if box is not None:
        args += ["--target", f"127.0.0.1:{box.tcp_port}", "--udp-target", f"127.0.0.1:{box.udp_port}"]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    tmp_path.mkdir(parents=True, exist_ok=True)
    report_dir = tmp_path / "report"
    if _has_report_writer():
        args += ["--report-dir", str(report_dir)]
        summary = report_dir / "summary.json"
    else:
        summary = tmp_path / "dump.json"
        env[DUMP_ENV] = str(summary)
        args += ["-p", "tests.e2e.test_cases_extension_udp"]
    proc = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True, timeout=RUN_TIMEOUT_S)
    assert summary.is_file(), f"no results (exit {proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    doc = json.loads(summary.read_text(encoding="utf-8"))
    return {c["id"]: c for c in doc["cases"]}


def verdicts(results: dict[str, dict[str, Any]]) -> dict[str, str]:
    """Verdicts of the selected cases (T1-00, the always-run baseline, is checked separately)."""
    return {cid: c["verdict"] for cid, c in results.items() if cid != "T1-00"}


def failing(results: dict[str, dict[str, Any]]) -> dict[str, str]:
    return {cid: v for cid, v in verdicts(results).items() if v in ("FAIL", "NON-STRICT", "ERROR")}


@contextmanager
def reference_box(config: BoxConfig | None = None, patch: Patch | None = None) -> Iterator[BoxThread]:
    box = BoxThread(config or BoxConfig(), host="127.0.0.1").start()
    try:
        if patch is not None:
            box.call(lambda: patch(box.behaviour))
        yield box
    finally:
        box.stop()


# -- broken behaviours ------------------------------------------------------------------------------


def _replace_answer(action: Action, make: Callable[[BoxBehaviour], Frame]) -> Patch:
    """Answer every well-formed request with ``action`` by ``make(behaviour)``."""

    def patch(b: BoxBehaviour) -> None:
        frame = make(b)
        decision = Decision(Reaction.OK, frame, b.codec.encode(frame, Transport.TCP), b.codec.encode(frame, Transport.UDP),
                            "broken on purpose")
        original = b.decide

        def decide(event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
            if isinstance(event, Frame) and event.action == action:
                return decision
            return original(event, transport)

        b.decide = decide  # type: ignore[method-assign]
        b.fast_path = False  # every frame through the patched decide()

    return patch


def _swap_field(offset: int, when: Callable[[Frame], bool]) -> Patch:
    """Reads big-endian, but writes the 2-byte field at ``offset`` little-endian in some answers (F4)."""

    def patch(b: BoxBehaviour) -> None:
        original = b.decide

        def decide(event: Frame | ProtocolError, transport: Transport = Transport.TCP) -> Decision:
            d = original(event, transport)
            if d.frame is None or d.tcp is None or not when(d.frame):
                return d
            tcp = d.tcp[:offset] + d.tcp[offset:offset + 2][::-1] + d.tcp[offset + 2:]
            return Decision(d.reaction, d.frame, tcp, d.udp, d.note)

        b.decide = decide  # type: ignore[method-assign]
        b.fast_path = False  # every frame through the patched decide()

    return patch


def _udp_wrong_crc(b: BoxBehaviour) -> None:
    original = b.receive_datagram

    def receive(data: bytes, trace: Any = None) -> bytes | None:
        out = original(data, trace)
        return out[:-2] + bytes([out[-2] ^ 0xFF, out[-1]]) if out else out

    b.receive_datagram = receive  # type: ignore[method-assign]


def _udp_answers_bad_crc(error: int) -> Patch:
    """A datagram with a wrong CRC is answered (with ``error``) instead of dropped (R7)."""

    def patch(b: BoxBehaviour) -> None:
        original = b.receive_datagram

        def receive(data: bytes, trace: Any = None) -> bytes | None:
            try:
                b.codec.parse(data, Transport.UDP, TransferType.ROBOT_TO_BOX)
            except ProtocolError as exc:
                if exc.clause == "F7" and exc.header is not None:
                    return b.codec.encode(answer(Action(exc.header.action), error), Transport.UDP)
            return original(data, trace)

        b.receive_datagram = receive  # type: ignore[method-assign]

    return patch


# -- the bundled box: everything passes ---------------------------------------------------------------


CASES = ["E1-*", "E2-*", "E3-*", "E4-*", "E5-*", "F7-*", "R7-*", "F4-*", "PROFILE-*"]


def test_bundled_box_passes(tmp_path: Path) -> None:
    results = run_suite(tmp_path, CASES)
    assert not failing(results), results
    v = verdicts(results)
    mine = [f"E1-01[{p}]" for p in ("negative", "int32-min", "int32-max", "bytes")] + [
        "E2-01", "E3-01", "E3-02", "E4-01", "E5-01", "F7-01", "F7-02", "F7-03", "F7-04", "F4-01", "PROFILE-01",
    ] + [f"R7-01[{k}]" for k in ("wrong-crc", "truncated", "trailing-bytes", "two-frames", "truncated-after-whole")]
    assert {cid: v.get(cid) for cid in mine} == {cid: "INFORMATIONAL" if cid == "PROFILE-01" else "PASS" for cid in mine}
    assert v["PROFILE-01"] == "INFORMATIONAL"
    assert "the profile in use fits" in results["PROFILE-01"]["message"]
    assert "modbus, big-endian" in results["PROFILE-01"]["message"]
    assert sum(c["duration_s"] for c in results.values()) < 5.0


# -- E ------------------------------------------------------------------------------------------------


def test_result_code_404_fails_e3(tmp_path: Path) -> None:
    patch = _replace_answer(Action.VISION_RESULT, lambda b: answer(Action.VISION_RESULT, 0, value_blocks([404])))
    with reference_box(patch=patch) as box:
        auto = run_suite(tmp_path / "auto", ["E*"], box)
        forced = run_suite(tmp_path / "on", ["E*"], box, "--extension", "on")
    # the box answers 27 (wrongly): detection counts that as implementing E, so E4 runs and fails too; E3-02 judges
    # the run's first 27 (the detection's, or with --extension on the one sent at session start)
    assert failing(auto) == {"E3-01": "FAIL", "E3-02": "FAIL", "E4-01": "FAIL"}, verdicts(auto)
    assert "404" in auto["E3-01"]["message"]
    assert failing(forced) == {"E3-01": "FAIL", "E3-02": "FAIL", "E4-01": "FAIL"}, verdicts(forced)


def test_prog_idx_without_block_fails_e2(tmp_path: Path) -> None:
    with reference_box(patch=_replace_answer(Action.PROG_IDX, lambda b: answer(Action.PROG_IDX))) as box:
        results = run_suite(tmp_path, ["E*"], box)
    bad = failing(results)
    assert bad.pop("E2-01") == "FAIL"
    assert bad.pop("E4-01") == "FAIL"
    assert bad == {f"E1-01[{p}]": "FAIL" for p in ("negative", "int32-min", "int32-max", "bytes")}
    assert verdicts(results)["E3-01"] == verdicts(results)["E5-01"] == "PASS"
    assert "E2" in results["E2-01"]["message"]


def test_prog_idx_conflict_placement(tmp_path: Path) -> None:
    conflict = BoxConfig(progidx_conflict=True, profile=Profile(progidx_conflict="error-code"))
    with reference_box(conflict) as box:
        as_block = run_suite(tmp_path / "block", ["E2-*"], box)
        as_error = run_suite(tmp_path / "error", ["E2-*", "E4-*"], box, "--progidx-conflict", "error-code")
    assert verdicts(as_block) == {"E2-01": "FAIL"}
    assert "--progidx-conflict=error-code" in as_block["E2-01"]["message"]
    assert verdicts(as_error) == {"E2-01": "INFORMATIONAL", "E4-01": "INCONCLUSIVE"}


def test_box_without_extension_skips_e(tmp_path: Path) -> None:
    with reference_box(BoxConfig(extension=False)) as box:
        results = run_suite(tmp_path, ["E*", "F4-01"], box, "--time-out", "500")
    v = verdicts(results)
    assert v.pop("F4-01") == "PASS"
    assert v and set(v.values()) == {"SKIP"}, v


# -- UDP ----------------------------------------------------------------------------------------------


def test_udp_wrong_answer_crc_fails_f7(tmp_path: Path) -> None:
    with reference_box(patch=_udp_wrong_crc) as box:
        results = run_suite(tmp_path, ["F7-*", "R7-*"], box)
    assert failing(results) == {"F7-02": "FAIL", "F7-03": "FAIL", "F7-04": "FAIL"}, verdicts(results)
    assert "modbus" in results["F7-02"]["message"]
    assert verdicts(results)["F7-01"] == "PASS"


def test_udp_bad_crc_answered_0000_fails_r7(tmp_path: Path) -> None:
    with reference_box(patch=_udp_answers_bad_crc(0)) as box:
        results = run_suite(tmp_path, ["R7-*", "F7-*"], box)
    crc_bytes = {f"F7-05[check-byte{b}-x{m}]": "FAIL" for b in (0, 1) for m in ("01", "ff")}  # each CRC byte alone
    assert failing(results) == {"R7-01[wrong-crc]": "FAIL", **crc_bytes}, verdicts(results)


def test_udp_bad_crc_answered_error_is_non_strict(tmp_path: Path) -> None:
    with reference_box(patch=_udp_answers_bad_crc(0x1001)) as box:
        results = run_suite(tmp_path, ["R7-*"], box)
    assert failing(results) == {"R7-01[wrong-crc]": "NON-STRICT"}, verdicts(results)


# -- discovery and F4 ----------------------------------------------------------------------------------


def test_discovery_first_index_1_xmodem_little(tmp_path: Path) -> None:
    profile = Profile(first_index=1, crc="xmodem", crc_byte_order="little")
    with reference_box(BoxConfig(profile=profile)) as box:
        found = run_suite(tmp_path / "found", ["PROFILE-*", "F7-01"], box, "--time-out", "500")
        flags = ["--first-index=1", "--crc=xmodem", "--crc-byte-order=little"]
        rerun = run_suite(tmp_path / "rerun", CASES, box, *flags)
    message = found["PROFILE-01"]["message"]
    assert found["PROFILE-01"]["verdict"] == "INFORMATIONAL"
    assert "rerun with:" in message and all(f in message.split("rerun with:")[1].split() for f in flags), message
    assert "first block index 1" in message and "xmodem, little-endian" in message
    if "details" in found["PROFILE-01"]:
        suggested = found["PROFILE-01"]["details"]["suggested_flags"]
        assert sorted(suggested) == sorted([*flags, "--time-out=500"]), suggested
    assert failing(found), "the default profile does not fit this box"
    assert not failing(rerun), verdicts(rerun)
    assert "the profile in use fits" in rerun["PROFILE-01"]["message"]


def test_little_endian_box_fails_f4_and_is_discovered(tmp_path: Path) -> None:
    with reference_box(BoxConfig(profile=Profile(byte_order="little"))) as box:
        results = run_suite(tmp_path, ["F4-*", "PROFILE-*"], box, "--time-out", "500")
    # the box answers nothing in the default (big-endian) profile: the baseline FAILs and points
    # at PROFILE-01, which runs anyway and names the flag; F4-01 cannot be judged
    assert results["T1-00"]["verdict"] == "FAIL" and "PROFILE-01" in results["T1-00"]["message"]
    assert verdicts(results)["F4-01"] in ("FAIL", "INCONCLUSIVE")
    assert "--byte-order=little" in results["PROFILE-01"]["message"]


def test_swapped_fields_fail_f4(tmp_path: Path) -> None:
    with reference_box(patch=_swap_field(10, lambda f: f.error_code == 0x1001)) as box:
        error = run_suite(tmp_path / "error", ["F4-01"], box)  # F4-02 changes bytes of requests
    with reference_box(patch=_swap_field(8, lambda f: f.action == Action.PROG_IDX)) as box:
        length = run_suite(tmp_path / "length", ["F4-01"], box, "--time-out", "500")
    assert verdicts(error) == {"F4-01": "FAIL"}
    assert "error code 1001 in the other byte order" in error["F4-01"]["message"]
    assert verdicts(length) == {"F4-01": "FAIL"}
    assert "block length 5 in the other byte order" in length["F4-01"]["message"]
