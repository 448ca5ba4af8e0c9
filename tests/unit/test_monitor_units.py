"""The monitor's sans-I/O parts: the splitter, fault specs, root causes, excused findings, the ring."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conformance.analyze.capture import CaptureReader
from conformance.analyze.findings import BOX, ROBOT
from conformance.model.verdicts import Verdict
from conformance.monitor.faults import FaultPlan, corrupt, parse_fault
from conformance.monitor.live_findings import MAX_CAUSES, LiveFindings, signature
from conformance.monitor.ring import Ring
from conformance.monitor.split import Splitter
from conformance.protocol import Action, Profile

POSE = bytes.fromhex("fefe0001102300000000000000 00".replace(" ", ""))  # a pose answer, 0000
CYCLE_ON = bytes.fromhex("fefe00010101000000000000 0000".replace(" ", ""))

pieces = st.lists(st.one_of(st.sampled_from([POSE, CYCLE_ON, b"\xfe", b"\xfe\xfe", b"\xfe\xfe\x00\x01"]),
                            st.binary(max_size=40)), max_size=40)


@settings(max_examples=200, deadline=None)
@given(pieces, st.lists(st.integers(1, 50), min_size=1, max_size=20))
def test_the_splitter_gives_every_byte_back_in_order(parts: list[bytes], cuts: list[int]) -> None:
    data = b"".join(parts)
    split, out, at, i = Splitter(), [], 0, 0
    while at < len(data):
        n = cuts[i % len(cuts)]
        out += split.feed(data[at : at + n])
        at, i = at + n, i + 1
    rest = split.flush()
    assert b"".join(p for p, _ in out) + rest == data
    assert split.pending == 0


def test_the_splitter_names_each_frames_action() -> None:
    out = Splitter().feed(b"xy" + POSE + CYCLE_ON)
    assert out == [(b"xy", None), (POSE, Action.POSE), (CYCLE_ON, Action.CYCLE_ON)]


@pytest.mark.parametrize(("spec", "kind", "action", "value"), [
    ("delay:CYCLE_ON:6000", "delay", 1, 6000.0), ("drop:pose,every=10", "drop", 0x23, None),
    ("error:cycle-on:1", "error", 1, 1), ("corrupt:0x02:check", "corrupt", 2, "check"),
    ("close:CycleOff", "close", 2, None), ("stall:any:250", "stall", None, 250.0),
])
def test_fault_specs(spec: str, kind: str, action: int | None, value: object) -> None:
    fault = parse_fault(spec)
    assert (fault.kind, fault.action) == (kind, action)
    assert value in (None, fault.ms, fault.code, fault.field_name)


@pytest.mark.parametrize("spec", ["delay:CYCLE_ON", "nope:1", "drop:BOGUS", "drop:1,every=0", "drop:1,p=2",
                                  "corrupt:1:nofield", "delay:1:-5", "drop:1,colour=red", "error:1:70000"])
def test_bad_fault_specs_are_one_line_errors(spec: str) -> None:
    with pytest.raises(ValueError, match="--fault") as info:
        parse_fault(spec)
    assert "\n" not in str(info.value)


def test_every_nth_and_count_and_after() -> None:
    fault = parse_fault("drop:POSE,every=3,count=2")
    hits = [fault.hit(0x23, 1.0) for _ in range(12)]
    assert hits == [False, False, True, False, False, True] + [False] * 6
    assert not parse_fault("drop:POSE,after=5").hit(0x23, 4.9)
    assert not parse_fault("drop:POSE").hit(0x01, 1.0)


def test_probability_faults_repeat_with_their_seed() -> None:
    plans = [FaultPlan(["drop:POSE,p=0.3"], seed=11) for _ in range(2)]
    runs = [[plan.pick(0x23, 0.0) is not None for _ in range(100)] for plan in plans]
    assert runs[0] == runs[1] and 10 < sum(runs[0]) < 60


def test_corrupt_inverts_one_field() -> None:
    assert corrupt(CYCLE_ON, "version")[2:4] == b"\xff\xfe"
    assert corrupt(CYCLE_ON, "check")[-2:] == b"\xff\xff"
    assert corrupt(CYCLE_ON, "body") == CYCLE_ON[:-1] + b"\xff"  # no body: its last byte
    assert corrupt(CYCLE_ON, "action")[5] == 0xFE


def test_findings_are_grouped_by_what_stays_the_same() -> None:
    a = "conn 3 (10.0.0.2:5100 → 10.0.0.1:9004): CYCLE_ON answered after 6012.3 ms; the bound is 5000 ms"
    b = "conn 9 (10.0.0.2:5230 → 10.0.0.1:9004): CYCLE_ON answered after 6100.0 ms; the bound is 5000 ms"
    assert signature(a) == signature(b)
    seen = []
    f = LiveFindings(lambda clause, side, finding, cause: seen.append((clause, side, cause.count)), clock=lambda: 5.0)
    f.add("T1", BOX, Verdict.FAIL, a, (10, 11))
    f.add("T1", BOX, Verdict.FAIL, b, (20, 21))
    f.add("S1", ROBOT, Verdict.FAIL, "session 1: CycleOn before the stream")
    assert seen == [("T1", BOX, 1), ("T1", BOX, 2), ("S1", ROBOT, 1)]
    assert [(c.clause, c.count) for c in f.roots.ordered()] == [("T1", 2), ("S1", 1)]
    assert f.count("T1", BOX, Verdict.FAIL) == 2  # analyze's tallies, as ever


def test_root_causes_stay_bounded() -> None:
    f = LiveFindings()
    for n in range(MAX_CAUSES + 50):
        f.add("F1", BOX, Verdict.FAIL, f"conn 1 (a → b): odd thing {'x' * (n % 300)}")
    assert len(f.roots.causes) == MAX_CAUSES + 1
    assert sum(c.count for c in f.roots.causes.values()) == MAX_CAUSES + 50


def test_a_fault_excuses_what_it_caused_and_nothing_else() -> None:
    f = LiveFindings()
    f.fault_on(2, 50, event=1, written=52)
    f.add("T1", BOX, Verdict.FAIL, "conn 2 (a → b): no answer to CYCLE_ON within 5000 ms", (50,))
    f.add("A1", ROBOT, Verdict.FAIL, "conn 2 (a → b): CYCLE_OFF sent before the answer", (60,))
    f.add("F2", BOX, Verdict.FAIL, "conn 2 (a → b), offset 14: version", (52,))
    assert f.excused_count == 3 and len(f.excused[1]) == 3 and not f.roots.causes
    f.add("T1", BOX, Verdict.FAIL, "conn 2 (a → b): no answer to NONE within 5000 ms", (40,))  # before the fault
    f.add("F2", BOX, Verdict.FAIL, "conn 2 (a → b), offset 28: version", (70,))  # a frame the box wrote
    f.add("T1", BOX, Verdict.FAIL, "conn 3 (a → b): no answer to CYCLE_ON within 5000 ms", (80,))  # another conn
    f.add("F3", ROBOT, Verdict.FAIL, "conn 2 (a → b), offset 0: transfer type 10", (61,))  # the robot's frame
    assert f.excused_count == 3 and len(f.roots.causes) == 4


def test_the_ring_keeps_n_files_each_readable_on_its_own(tmp_path: Path) -> None:
    ring = Ring(tmp_path, files=3, file_mb=0.01)
    frame = bytes(12) + b"\x08\x00" + random.Random(1).randbytes(500)
    for no in range(1, 201):
        ring.write(frame, 1_700_000_000.0 + no / 1000, no, ["a comment"] if no == 7 else None)
    ring.close()
    files = sorted(tmp_path.glob("*.pcapng"))
    assert [p.name for p in files] == [e["file"] for e in ring.index()] and len(files) == 3
    assert ring.deleted > 0 and ring.disk_bytes() <= 3 * (10_000 + 600)
    counted = 0
    for path in files:
        reader = CaptureReader(path)
        packets = list(reader.packets())
        reader.close()
        assert reader.truncated is None and packets and packets[0][3] == frame
        counted += len(packets)
    assert ring.index()[-1]["first_frame"] == 200 - len(packets) + 1
    assert counted == 200 - ring.index()[0]["first_frame"] + 1


def test_the_ring_refuses_nonsense() -> None:
    with pytest.raises(ValueError):
        Ring(Path("x"), files=0)
    with pytest.raises(ValueError):
        Ring(Path("x"), file_mb=0)


def test_without_a_terminal_a_status_line_every_minute(tmp_path: Path) -> None:
    import io

    from conformance.analyze.analysis_context import AnalyzeConfig
    from conformance.monitor.hub import Hub, MonitorSettings
    from conformance.monitor.view import STATUS_EVERY_S, View

    out = io.StringIO()
    view = View(out, tty=False)
    hub = Hub(MonitorSettings(("127.0.0.1", 1), ("127.0.0.1", 9004), AnalyzeConfig(ports=(9004,)), None),
              on_finding=view.finding)
    view.start(hub)
    view.tick()
    assert out.getvalue() == ""  # not a minute yet
    view.last_status -= STATUS_EVERY_S
    conn = hub.opened(("127.0.0.1", 40000), ("127.0.0.1", 9004))
    hub.data(conn, True, bytes.fromhex("fefe00010101000000000000 0000".replace(" ", "")))
    hub.data(conn, False, bytes.fromhex("fefe00010101000000000000 0000".replace(" ", "")))  # transfer type 01: F3
    view.tick()
    lines = out.getvalue().splitlines()
    assert lines[0].split(" ", 1)[1].startswith("FAIL BOX F3: frame")
    assert "status: 1 open / 1 connection(s)" in lines[1] and "frames robot→box 1 box→robot 1" in lines[1]


def test_what_the_robot_did_after_a_fault() -> None:
    from conformance.monitor.reactions import DETAILED, Reactions

    r = Reactions(Profile(time_out_ms=5000))
    a = r.injected("drop:CYCLE_ON", "drop", "A1", line=1, robot_host="10.0.0.2", action=1, t=100.0, frame=9,
                   what="CYCLE_ON answer dropped")
    b = r.injected("drop:CYCLE_OFF", "drop", "A1", line=3, robot_host="10.0.0.3", action=2, t=100.0, frame=9,
                   what="CYCLE_OFF answer dropped")
    r.request(1, 1, 100.5)  # robot 10.0.0.2 sends CycleOn again on the same connection
    r.closed(1, False, 105.002)
    r.connected("10.0.0.2", 105.2)
    r.request(3, 0x23, 99.0)  # before the fault: not a reaction
    r.closed(3, True, 200.0)  # after the window (2 x time_out + 5 s): not followed any more
    assert a.summary(5000) == ("sent CYCLE_ON again after 500 ms; then closed the connection after 5002 ms "
                               "(its time_out, 5000 ms); then reconnected after 5200 ms")
    assert b.moves == [] and b.summary(5000) == "the robot did nothing the monitor saw afterwards"
    for n in range(DETAILED + 5):
        r.injected("drop:POSE", "drop", "A1", 4, "h", 0x23, 300.0 + n, 100 + n, "POSE answer dropped")
    assert r.total == 2 + DETAILED + 5 and len(r.injections) == 2 + DETAILED


def test_a_judgement_that_fails_is_the_suites_error_and_the_line_goes_on(tmp_path: Path) -> None:
    from conformance.monitor.line_recording import Wire

    class Broken:
        calls = 0

        def packet(self, *args: object) -> None:
            Broken.calls += 1
            raise RuntimeError("boom")

    ring = Ring(tmp_path)
    wire = Wire(Broken(), ring, "t")  # type: ignore[arg-type]
    line = wire.line(("127.0.0.1", 40000), ("127.0.0.1", 9004))
    wire.opened(line)
    assert wire.data(line, True, b"abc") == 4
    ring.close()
    assert wire.judge_errors == Broken.calls == 4 and wire.judge_error == "frame 1: RuntimeError: boom"
    reader = CaptureReader(ring.kept[0][0])
    assert sum(1 for _ in reader.packets()) == 4  # recorded all the same
    reader.close()
