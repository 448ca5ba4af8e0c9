"""conformance.runtime.run_state: baseline, S4 preflight and witness, R2/S5 after a case, re-probes, known-late actions.

The boxes are tiny loopback servers written here (threads, every wait bounded, all joined at the end)."""

from __future__ import annotations

import contextlib
import re
import socket
import threading
import time
from collections.abc import Callable, Iterator
from types import SimpleNamespace

import pytest

from conformance.harness.client import Answer, Closed, Malformed, Silence, TcpConnection
from conformance.harness.target import Target
from conformance.harness.transcript import Kind, Transcript
from conformance.model.signature import DeathKind, Sig, Signature
from conformance.model.verdicts import Verdict
from conformance.protocol import Action, Profile, StreamDecoder, TransferType, answer, encode, request
from conformance.protocol.errors import ProtocolError
from conformance.protocol.frames import Frame
from conformance.runtime import run_state as session_mod
from conformance.runtime.run_state import (
    LATE_CASES,
    RECHECK_S,
    S5_TEXT,
    UNREACHABLE_AT_CONNECT,
    SessionState,
    responsive,
)
from conformance.runtime.settings import SuiteSettings
from conformance.suite.case_judge import CaseVerdict, Inconclusive

PROFILE = Profile(time_out_ms=500)  # every silence in these tests costs at most this
POLL = 0.05


class Requests:
    """The requests of each read on ``conn`` (a list per read), until the robot closes (``eof`` then
    True), the connection fails, or ``stop`` is set. ``conn`` has a short timeout (POLL)."""

    def __init__(self, conn: socket.socket, stop: threading.Event) -> None:
        self.conn, self.stop, self.eof = conn, stop, False
        self.decoder = StreamDecoder(PROFILE, TransferType.ROBOT_TO_BOX)

    def __iter__(self) -> Iterator[list[Frame]]:
        while not self.stop.is_set():
            try:
                data = self.conn.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                self.eof = True
                return
            self.decoder.receive_data(data)
            yield [e for e in self.decoder.events() if isinstance(e, Frame)]


def answers_to(frames: list[Frame]) -> bytes:
    return b"".join(encode(answer(f.action), PROFILE) for f in frames)


class Box:
    """A loopback box. ``mode``: "answer" (every connection served at once, each request answered 0000),
    "one" (one connection at a time: the next waits in the listen queue), "silent" (accepts, never answers),
    "leak" (answers, never closes a connection, stops accepting after ``capacity``). ``mute`` makes every
    connection silent; a box made with ``listening=False`` refuses connections until :meth:`start`."""

    def __init__(self, mode: str = "answer", capacity: int = 0, listening: bool = True) -> None:
        self.mode, self.capacity = mode, capacity
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.accepted = 0
        self.eofs = 0  # connections the robot closed
        self.mute = threading.Event()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._threads: list[threading.Thread] = []
        self._conns: list[socket.socket] = []
        if listening:
            self.start()

    def start(self) -> None:
        self.sock.listen(16)
        self.sock.settimeout(POLL)
        self._spawn(self._accept_loop)

    def _spawn(self, fn: Callable[..., None], *args: object) -> None:
        thread = threading.Thread(target=fn, args=args, daemon=True)
        with self._lock:
            self._threads.append(thread)
        thread.start()

    def _accept_loop(self) -> None:
        while not self._stop.is_set():
            if self.mode == "leak" and self.accepted >= self.capacity:
                self._stop.wait(POLL)  # the leaked connections fill it: it accepts no more
                continue
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.settimeout(POLL)
            with self._lock:
                self.accepted += 1
                self._conns.append(conn)
            if self.mode == "one":
                self._serve(conn)  # inline: no other connection is accepted meanwhile
            else:
                self._spawn(self._serve, conn)

    def _serve(self, conn: socket.socket) -> None:
        reads = Requests(conn, self._stop)
        for frames in reads:
            if self.mode == "silent" or self.mute.is_set():
                continue
            try:
                conn.sendall(answers_to(frames))
            except OSError:
                break
        if reads.eof:
            with self._lock:
                self.eofs += 1
        if self.mode != "leak":  # a leaking box never closes its side
            with contextlib.suppress(OSError):
                conn.close()

    def close(self) -> None:
        """Stop every thread, then close every socket (the box is gone: connections refused)."""
        self._stop.set()
        for _ in range(2):  # the accept thread may still be spawning handlers on the first pass
            with self._lock:
                threads = list(self._threads)
            for thread in threads:
                thread.join(5)
        for sock in [self.sock, *self._conns]:
            with contextlib.suppress(OSError):
                sock.close()


Make = Callable[..., tuple[Box, SessionState]]


@pytest.fixture
def boxed() -> Iterator[Make]:
    """``boxed(mode, capacity, listening)``: a box and a session testing it; both stopped at the end."""
    made: list[tuple[Box, SessionState]] = []

    def make(mode: str = "answer", capacity: int = 0, listening: bool = True,
             extension: str = "off") -> tuple[Box, SessionState]:
        # extension off: the connections counted here are the baseline's and the preflight's; with auto (the
        # default of a run) the session start also sends the run's first result request (E3-02), tested below
        box = Box(mode, capacity, listening)
        made.append((box, SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=PROFILE,
                                                     extension=extension))))
        return made[-1]

    yield make
    for box, state in made:
        state.stop()
        box.close()
    assert not any(t.is_alive() for box, _ in made for t in box._threads)


def wait_for(check: Callable[[], bool], within: float = 5.0) -> bool:
    deadline = time.monotonic() + within
    while not check() and time.monotonic() < deadline:
        time.sleep(0.01)
    return check()


def labels(transcript: Transcript) -> list[str]:
    return [info.label for info in transcript.connections.values()]


def ready(state: SessionState, case_id: str = "C-0") -> Transcript:
    transcript = Transcript(case_id)
    state.before_case(case_id, transcript)
    return transcript


# -- baseline and preflight --------------------------------------------------------------------------


def test_the_session_start_sends_the_runs_first_result_request_after_the_preflight(boxed: Make) -> None:
    box, state = boxed(extension="auto")
    transcript = ready(state, "C-1")
    assert labels(transcript)[3] == "session start: the first result request (E3)"
    assert box.accepted == 4 and state.first_result is not None and state.extension_supported is not None
    ready(state, "C-2")  # once per session
    assert box.accepted == 4


def test_a_box_serving_connections_at_once_keeps_a_witness(boxed: Make) -> None:
    assert encode(answer(Action.NONE)) == bytes.fromhex("fe fe 00 01 10 00 00 00 00 00 00 00 00 00")  # what it answers
    box, state = boxed()
    transcript = ready(state, "C-1")
    assert isinstance(state.baseline, Answer) and state.baseline_ok()
    assert state.concurrent is True and state.concurrency_note == ""
    assert state.answered == {"NONE"} and state.deaths == [] and state.health.dead_since_case is None
    assert labels(transcript)[:3] == ["liveness", "preflight: first connection", "preflight: second connection, first open"]
    assert box.accepted == 3 and wait_for(lambda: box.eofs == 2)  # the baseline's and the second closed
    witness = state._witness
    assert witness is not None and witness.transcript is not transcript  # it outlives the case's transcript
    ready(state, "C-2")  # baseline and preflight run once per session
    assert box.accepted == 3
    state.stop()
    assert state._witness is None and wait_for(lambda: box.eofs == 3)


def test_a_box_serving_one_connection_at_a_time_is_s4_not_a_death(boxed: Make) -> None:
    box, state = boxed("one")
    ready(state)  # does not raise: the box is alive
    assert state.concurrent is False and state._witness is None
    assert "a second connection's NONE request stayed silent" in state.concurrency_note
    assert "once the first closed, it was answered (answered box→robot NONE err=0x0000)" in state.concurrency_note
    assert state.deaths == [] and state.health.dead_since_case is None


@pytest.mark.parametrize(("how", "kind", "words"), [({"mode": "silent"}, Silence, "stayed silent"),
                                                    ({"listening": False}, Closed, "reset the connection")])
def test_a_box_that_never_answers_ends_every_case_inconclusive_at_once(boxed: Make,
                                                                       how: dict, kind: type, words: str) -> None:
    box, state = boxed(**how)
    with pytest.raises(Inconclusive) as raised:
        ready(state, "C-1")
    assert str(raised.value.signature) == "unreachable:session start"
    assert isinstance(state.baseline, kind) and not state.baseline_ok()
    assert state.concurrent is None and box.accepted <= 1  # no preflight on a box that never answered
    assert [(d.case_id, d.kind) for d in state.deaths] == [("session start", DeathKind.UNRESPONSIVE)]
    assert words in state.deaths[0].detail
    later = Transcript("C-2")
    with pytest.raises(Inconclusive):
        state.before_case("C-2", later)
    assert later.connections == {}  # refused at once: no connection, no wait
    state.before_case("PROFILE-01", later, any_profile=True)  # profile discovery still runs


def test_responsive_means_frame_like() -> None:
    def malformed(data: bytes) -> Malformed:
        decoder = StreamDecoder(PROFILE, TransferType.BOX_TO_ROBOT)
        decoder.receive_data(data)
        decoder.receive_data(b"")
        error = next(decoder.events())
        assert isinstance(error, ProtocolError)
        return Malformed(error, 0.0)

    assert responsive(malformed(encode(request(Action.NONE))))  # a header, in the wrong direction
    assert not responsive(malformed(b"no"))  # no header: not frame-like
    assert not responsive(Silence(0.5)) and not responsive(Closed(True, 0.0))


# -- after a case -------------------------------------------------------------------------------------


def case_connection(state: SessionState, transcript: Transcript) -> TcpConnection:
    conn = TcpConnection(transcript, state.target(), PROFILE, "command").connect()
    assert isinstance(conn.request(request(Action.NONE)), Answer)
    return conn


def test_a_clean_case_is_not_probed_and_its_connections_are_counted(boxed: Make) -> None:
    box, state = boxed()
    transcript = ready(state)  # the case shares the transcript, as under the plugin
    case_connection(state, transcript).close()
    left_open = case_connection(state, transcript)
    error = CaseVerdict(Verdict.FAIL, "A3: wrong answer", signature=Signature(Sig.ANSWER, clause="A3"))
    assert state.after_case("C-0", transcript, malformed_input=False, last_sent=b"", error=error) is error
    left_open.close()
    assert box.accepted == 5  # baseline, two preflight, two of the case: no liveness probe
    assert (state.opened, state.closed) == (5, 3)  # the witness and the last one are open
    assert state.late == {}


@pytest.mark.parametrize(("malformed", "timeouts", "error", "probed"), [
    (True, 0, None, ["liveness"]), (False, 1, None, ["liveness"]),
    (True, 1, Inconclusive("box unreachable"), []),  # it never reached the box: nothing to learn
])
def test_malformed_input_or_a_time_out_checks_a_live_box(boxed: Make, malformed: bool, timeouts: int,
                                                         error: Inconclusive | None, probed: list[str]) -> None:
    box, state = boxed()
    ready(state)
    transcript = Transcript("C-1")
    transcript.timeouts = timeouts
    assert state.after_case("C-1", transcript, malformed_input=malformed, last_sent=b"\xff", error=error) is error
    assert labels(transcript) == probed and box.accepted == 3 + len(probed)
    assert state.deaths == [] and state.health.dead_since_case is None


def test_case_connections_are_closed_before_the_liveness_check(boxed: Make) -> None:
    box, state = boxed("one")
    ready(state)
    closed_first = Transcript("C-1")
    case_connection(state, closed_first).close()  # what the plugin's close_all does before after_case
    assert state.after_case("C-1", closed_first, malformed_input=True, last_sent=b"", error=None) is None
    assert state.deaths == []
    left_open = Transcript("C-2")  # the order matters: a box serving one connection is busy until it closes
    conn = case_connection(state, left_open)
    verdict = state.after_case("C-2", left_open, malformed_input=True, last_sent=b"", error=None)
    conn.close()
    assert isinstance(verdict, CaseVerdict) and str(verdict.signature) == "dead:C-2"


def test_a_box_gone_after_malformed_input_is_an_r2_failure(boxed: Make) -> None:
    box, state = boxed()
    ready(state)
    box.close()  # killed by the case: refuses new connections, closed the witness too
    verdict = state.after_case("C-1", Transcript("C-1"), malformed_input=True, last_sent=b"\xfe\xfe\x00", error=None)
    assert isinstance(verdict, CaseVerdict) and verdict.verdict is Verdict.FAIL
    assert verdict.judged == ("R2",) and str(verdict.signature) == "dead:C-1" and verdict.sent == b"\xfe\xfe\x00"
    assert [(d.case_id, d.kind) for d in state.deaths] == [("C-1", DeathKind.DEAD_AFTER_INPUT)]
    assert re.search(r"and a connection it accepted earlier (closed|reset) the connection too$", state.deaths[0].detail)
    assert state._witness is None and state.health.dead_since_case == "C-1"
    later = Transcript("C-2")
    with pytest.raises(Inconclusive) as raised:
        state.before_case("C-2", later)
    assert str(raised.value.signature) == "unreachable:C-1" and later.connections == {}
    again = Transcript("C-2")  # already known unreachable: no second probe, no second death
    assert state.after_case("C-2", again, malformed_input=True, last_sent=b"", error=None) is None
    assert again.connections == {} and len(state.deaths) == 1


def test_a_box_that_stops_accepting_but_answers_the_witness_breaks_s5(boxed: Make) -> None:
    box, state = boxed("leak", capacity=3)  # the baseline and the two preflight connections fill it
    ready(state)
    assert state.concurrent is True
    verdict = state.after_case("C-1", Transcript("C-1"), malformed_input=True, last_sent=b"\x00", error=None)
    assert isinstance(verdict, CaseVerdict) and verdict.verdict is Verdict.FAIL
    assert verdict.judged == ("S5",) and str(verdict.signature) == "not-accepting" and verdict.requirement == S5_TEXT
    death = state.deaths[-1]
    assert (death.case_id, death.kind) == ("C-1", DeathKind.CONNECTION_LEAK)
    assert "yet it answers on a connection it accepted earlier" in death.detail
    assert state._witness is not None and box.accepted == 3


def test_a_case_that_could_not_connect_looks_for_the_death_and_is_explained_by_it(boxed: Make) -> None:
    """A box that stops accepting during an ordinary case: the case's failed connect starts the diagnosis."""
    box, state = boxed("leak", capacity=3)
    ready(state)
    refused = Inconclusive("box unreachable: connect timed out", signature=UNREACHABLE_AT_CONNECT)
    assert state.after_case("C-1", Transcript("C-1"), malformed_input=False, last_sent=b"", error=refused) is refused
    assert [(d.case_id, d.kind) for d in state.deaths] == [("C-1", DeathKind.CONNECTION_LEAK)]
    assert state.health.dead_since_case == "C-1"
    with pytest.raises(Inconclusive) as later:  # the later cases are refused at once, blamed on C-1
        state.before_case("C-2", Transcript("C-2"))
    assert str(later.value.signature) == "unreachable:C-1"


def test_an_ordinary_inconclusive_case_does_not_probe(boxed: Make) -> None:
    box, state = boxed()
    ready(state)
    before = box.accepted
    not_ready = Inconclusive("S2: CycleOn answered 0001")
    transcript = Transcript("C-1")
    transcript.timeouts = 1
    assert state.after_case("C-1", transcript, malformed_input=True, last_sent=b"", error=not_ready) is not_ready
    assert box.accepted == before and state.deaths == []


class SingleBox:
    """An embedded stack with room for one connection: while one is open, new ones are refused (RST)."""

    def __init__(self, relisten_after: float = 0.0) -> None:
        self.relisten_after = relisten_after  # how long it takes to free its slot once a connection closed
        self.listener = self._listen(0)
        self.port = self.listener.getsockname()[1]
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    @staticmethod
    def _listen(port: int) -> socket.socket:
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(("127.0.0.1", port))
        sock.listen(1)
        sock.settimeout(POLL)
        return sock

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self.listener.close()  # nothing listens while this connection is open: connects are refused
            conn.settimeout(POLL)
            with conn:
                for frames in Requests(conn, self._stop):
                    with contextlib.suppress(OSError):
                        conn.sendall(answers_to(frames))
            if not self._stop.wait(self.relisten_after):
                self.listener = self._listen(self.port)

    def close(self) -> None:
        self._stop.set()
        self.thread.join(5)
        self.listener.close()


@pytest.mark.parametrize("relisten_after", [0.0, 0.3], ids=["frees-at-once", "frees-its-slot-later"])
def test_a_second_connection_refused_while_the_first_is_open_is_s4(relisten_after: float) -> None:
    box = SingleBox(relisten_after)  # 0.3 s: still within the time_out (0.5 s) the preflight retries for
    state = SessionState(SuiteSettings(target=Target("127.0.0.1", box.port), profile=PROFILE))
    try:
        ready(state)
        assert state.concurrent is False and state.deaths == [] and state.baseline_ok()
        assert "a second connection was refused" in state.concurrency_note
        assert "once the first closed, a new connection was answered" in state.concurrency_note
    finally:
        state.stop()
        box.close()
    assert not box.thread.is_alive()


@pytest.mark.parametrize("malformed", [True, False])
def test_a_case_keeps_its_own_failure_and_the_death_is_added(boxed: Make,
                                                            malformed: bool) -> None:
    box, state = boxed()
    ready(state)
    box.close()
    transcript = Transcript("C-1")
    transcript.timeouts = 1  # without malformed input, a time_out alone: the death is recorded, not judged
    error = CaseVerdict(Verdict.FAIL, "R1: answered 0000 to a bad frame", judged=("R1",), signature=Signature.own("r1"))
    assert state.after_case("C-1", transcript, malformed_input=malformed, last_sent=b"", error=error) is error
    assert [(d.case_id, d.kind) for d in state.deaths] == [("C-1", DeathKind.DEAD_AFTER_INPUT)]
    assert state.health.dead_since_case == "C-1"
    assert error.judged == (("R1", "R2") if malformed else ("R1",))
    assert error.message.startswith("R1: answered 0000 to a bad frame (and then R2: after this case's input") is malformed


def test_deaths_accumulate_with_what_the_suite_had_opened_and_closed(boxed: Make) -> None:
    box, state = boxed()
    first_case = ready(state, "C-1")  # a case's transcript holds what before_case opened too
    box.mute.set()  # hangs: accepts, answers nothing, not even on the witness
    assert isinstance(state.after_case("C-1", first_case, malformed_input=True, last_sent=b"", error=None), CaseVerdict)
    assert state._witness is None  # the witness went silent too: it is dropped
    box.mute.clear()
    state.health.next_check = 0.0  # the re-probe is due
    second_case = ready(state, "C-2")  # answered again: the case runs
    assert state.after_case("C-2", second_case, malformed_input=False, last_sent=b"", error=None) is None
    box.mute.set()
    state.after_case("C-3", Transcript("C-3"), malformed_input=True, last_sent=b"", error=None)
    assert [(d.case_id, d.kind) for d in state.deaths] == [("C-1", DeathKind.DEAD_AFTER_INPUT), ("C-3", DeathKind.DEAD_AFTER_INPUT)]
    assert "stayed silent" in state.deaths[0].detail and "a connection it accepted earlier stayed silent" in \
        state.deaths[0].detail
    first, second = state.deaths
    assert (first.opened, first.closed) == (4, 3)  # baseline, two preflight, the probe (the witness open)
    assert (second.opened, second.closed) == (6, 5)  # + the re-probe and the second probe


# -- re-probes on a wall-clock schedule -----------------------------------------------------------------


def test_a_dead_box_is_reprobed_every_recheck_s_of_the_clock(boxed: Make,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    now = [1000.0]  # the session's clock, moved by hand: no test waits RECHECK_S
    monkeypatch.setattr(session_mod, "time", SimpleNamespace(monotonic=lambda: now[0]))
    _, state = boxed(listening=False)
    with pytest.raises(Inconclusive):
        ready(state)
    assert state.health.next_check == 1000.0 + RECHECK_S
    probed: list[list[str]] = []
    for step in (0.0, RECHECK_S - 0.01, RECHECK_S, RECHECK_S + 5, 2 * RECHECK_S):
        now[0] = 1000.0 + step
        transcript = Transcript("C")
        with pytest.raises(Inconclusive, match="box unreachable since case session start"):
            state.before_case("C", transcript)
        probed.append(labels(transcript))
        assert all(e.kind == Kind.CONNECT_FAILED for e in transcript.events)  # refused: no wait
    assert probed == [[], [], ["re-probe"], [], ["re-probe"]] and state.health.next_check == 1000.0 + 3 * RECHECK_S


def test_a_box_that_comes_back_runs_cases_again(boxed: Make) -> None:
    box, state = boxed(listening=False)
    with pytest.raises(Inconclusive):
        ready(state)
    box.start()
    state.health.next_check = 0.0
    transcript = ready(state, "C-1")  # no exception: the case runs
    assert state.health.dead_since_case is None
    assert any(e.kind == Kind.NOTE and e.note == "the box answers again" for e in transcript.events)


# -- known-late actions ---------------------------------------------------------------------------------


def silence_fail(action: str) -> CaseVerdict:
    return CaseVerdict(Verdict.FAIL, f"T1: {action} unanswered", signature=Signature(Sig.SILENCE, action))


def settle(state: SessionState, case_id: str, error: BaseException) -> None:
    state.after_case(case_id, Transcript(case_id), malformed_input=False, last_sent=b"", error=error)


def test_an_action_is_known_late_after_enough_failed_cases(boxed: Make) -> None:
    _, state = boxed(listening=False)  # nothing here touches the box
    assert LATE_CASES == 2
    settle(state, "A-1", silence_fail("CYCLE_ON"))
    assert state.known_late("CYCLE_ON") is None
    settle(state, "A-2", Inconclusive("CYCLE_ON is not answered", signature=Signature(Sig.SILENCE, "CYCLE_ON")))  # not evidence
    settle(state, "A-3", CaseVerdict(Verdict.NON_STRICT, "slow", signature=Signature(Sig.SILENCE, "CYCLE_ON")))  # nor this
    assert state.known_late("CYCLE_ON") is None
    settle(state, "A-4", silence_fail("CYCLE_ON"))
    assert state.known_late("CYCLE_ON") == ["A-1", "A-4"]
    assert state.known_late("CYCLE_OFF") is None


def test_an_action_answered_in_time_once_is_never_known_late(boxed: Make) -> None:
    silent, _ = boxed("silent")
    _, state = boxed()
    transcript = Transcript("A")
    late = TcpConnection(transcript, Target("127.0.0.1", silent.port), PROFILE).connect()
    late.on_answered = state.note_answered
    assert isinstance(late.request(request(Action.CYCLE_ON), timeout_s=0.1), Silence)
    late.close()
    for case_id in ("A-1", "A-2"):
        settle(state, case_id, silence_fail("CYCLE_ON"))
    assert state.known_late("CYCLE_ON") == ["A-1", "A-2"]  # never answered: late
    conn = TcpConnection(transcript, state.target(), PROFILE).connect()
    conn.on_answered = state.note_answered
    assert isinstance(conn.request(request(Action.CYCLE_ON)), Answer)
    conn.close()
    assert "CYCLE_ON" in state.answered and state.known_late("CYCLE_ON") is None
    state.note_answered(0xEE)  # not an action: ignored
    assert state.answered == {"CYCLE_ON"}


# -- the target ---------------------------------------------------------------------------------------


def test_the_given_target_is_used_and_labelled() -> None:
    box, stream = Target("127.0.0.1", 9), Target("127.0.0.1", 10)
    state = SessionState(SuiteSettings(target=box, profile=PROFILE))
    assert state.target() is box and state.stream_target() is box and state.udp_target() is None
    assert state.target_label() == "127.0.0.1:9" and state.embedded is None and state.time_out_s == 0.5
    labelled = SessionState(SuiteSettings(target=box, stream_target=stream, target_label="line 3 box"))
    assert labelled.target_label() == "line 3 box" and labelled.stream_target() is stream
