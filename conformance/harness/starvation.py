"""Was the tester starved? A gauge of the suite's own scheduling delay, for timing verdicts (T1, T2).

On a loaded machine (a CI runner with more jobs than cores) the suite itself may not run
for tens or hundreds of milliseconds: it then reads an answer late, or sends a pose late,
and a timing figure it measured includes its own delay, not the peer's. Two remedies,
both here:

* :class:`StarvationGauge`: a timer thread that sleeps a short period and records how late
  it woke (its *lateness*: the time the process was kept from running). ``worst_ms`` over a
  time range is the longest the tester could have been kept away from its sockets then;
* :func:`starved_verdict`: the rule every timing judge applies (``run``, ``certify-robot``,
  ``monitor``): a T1/T2 breach by ``excess_ms`` while the gauge saw a stall of at least
  that long is INCONCLUSIVE ("the tester was starved"), never FAIL. A breach larger than
  any stall still FAILs: a robot at 45 Hz declared 50, a box whose latency grows, an answer
  after time_out;
* the host's CPU pressure (Linux PSI, ``/proc/pressure/cpu``: how long some task waited for a CPU),
  sampled by the same thread: when the peer runs on this host (a loopback address, as in a
  bench or CI test), its own sends can be delayed by the same contention, which the suite's
  timer cannot see. :func:`host_stall_ms` is that evidence for one stretch of time;
* :func:`enable_rx_timestamps` / :func:`recv_stamped`: kernel receive timestamps
  (``SO_TIMESTAMPNS``, the time the segment reached the socket, from ``recvmsg``'s ancillary
  data) on the suite's monotonic clock, so arrival times are the wire's, not the moment the
  suite got round to ``recv()``.

The gauge is cheap (one wake-up every :data:`PERIOD_S`) and keeps a bounded ring of its
stalls; start it around a timing case (:func:`gauge` is a process-wide, reference-counted
one).
"""

from __future__ import annotations

import asyncio
import bisect
import ipaddress
import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: How often the gauge's timer wakes (seconds).
PERIOD_S = 0.005
#: Lateness below this is the timer's own noise, not a stall (ms).
NOISE_MS = 2.0
#: How many stalls the gauge remembers (a bounded ring).
RING = 4096
#: ``SO_TIMESTAMPNS`` (Linux): not every Python build names it.
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)
SCM_TIMESTAMPNS = getattr(socket, "SCM_TIMESTAMPNS", SO_TIMESTAMPNS)
#: recvmsg's ancillary buffer: room for one struct timespec
_ANC = socket.CMSG_SPACE(16)
#: Linux pressure stall information for the CPU (absent on other systems and old kernels: no evidence then)
PSI_CPU = "/proc/pressure/cpu"
#: the host's CPU pressure is sampled every this many timer wakes (every 50 ms)
PSI_EVERY = 10
STARVED_TEXT = "the tester was starved"


@dataclass(frozen=True)
class Stall:
    at: float  # monotonic time the timer should have woken
    late_ms: float
    wall: float = 0.0  # the same moment on the wall clock (time.time(): certify-robot's and monitor's clocks)


class StarvationGauge:
    """A timer thread measuring how late it wakes: the process's scheduling delay over time."""

    def __init__(self, period_s: float = PERIOD_S) -> None:
        self.period_s = period_s
        self._stalls: deque[Stall] = deque(maxlen=RING)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._users = 0
        self.started_at = 0.0
        self.wakes = 0
        #: (monotonic, wall, cumulative µs during which some task waited for a CPU), oldest first
        self._pressure: deque[tuple[float, float, int]] = deque(maxlen=RING)
        self._psi_ok = True

    def start(self) -> StarvationGauge:
        with self._lock:
            self._users += 1
            if self._thread is None or not self._thread.is_alive():
                self._stop.clear()
                self._stalls.clear()  # a fresh watch (what it saw last time was judged when it stopped)
                self._pressure.clear()
                self.started_at = time.monotonic()
                self._thread = threading.Thread(target=self._run, name="isight-starvation-gauge", daemon=True)
                self._thread.start()
        return self

    def stop(self) -> None:
        with self._lock:
            self._users = max(0, self._users - 1)
            if self._users or self._thread is None:
                return
            self._stop.set()
            thread, self._thread = self._thread, None
        thread.join(1.0)

    def __enter__(self) -> StarvationGauge:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run(self) -> None:
        due = time.monotonic() + self.period_s
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            now = time.monotonic()
            late_ms = (now - due) * 1000
            self.wakes += 1
            if late_ms >= NOISE_MS:
                with self._lock:
                    self._stalls.append(Stall(due, late_ms, time.time() - late_ms / 1000))
            if self._psi_ok and self.wakes % PSI_EVERY == 1:
                self._sample_pressure()
            due = max(due + self.period_s, now)  # after a stall, the next wake is a period from now

    def _sample_pressure(self) -> None:
        total = read_psi_some_us()
        if total is None:
            self._psi_ok = False
            return
        self.note_pressure(time.monotonic(), time.time(), total)

    def note_pressure(self, at: float, wall: float, total_us: int) -> None:
        """Record one sample of the host's cumulative CPU stall (PSI "some" total, µs) at ``at``/``wall``."""
        with self._lock:
            self._pressure.append((at, wall, total_us))

    def host_stall_ms(self, since: float, until: float, wall: bool = False) -> float:
        """How long some task on this host waited for a CPU between the samples around ``since``..``until``
        (ms; 0 without samples covering both ends: no evidence)."""
        with self._lock:
            samples = list(self._pressure)
        times = [s[1 if wall else 0] for s in samples]  # ascending: sampled in order
        first, last = bisect.bisect_right(times, since) - 1, bisect.bisect_left(times, until)
        if first < 0 or last >= len(samples):
            return 0.0
        return (samples[last][2] - samples[first][2]) / 1000.0

    def note(self, at: float, late_ms: float) -> None:
        """Record a stall seen elsewhere (e.g. an event loop's timer that fired late)."""
        if late_ms >= NOISE_MS:
            with self._lock:
                self._stalls.append(Stall(at, late_ms, time.time() - (time.monotonic() - at)))

    def worst_ms(self, since: float = 0.0, until: float | None = None, wall: bool = False) -> float:
        """The longest stall that overlaps ``since``..``until`` (monotonic seconds; ``wall``: time.time()
        seconds, the clock certify-robot and monitor stamp frames with)."""
        end = (time.time() if wall else time.monotonic()) if until is None else until
        with self._lock:
            stalls = list(self._stalls)
        return max((s.late_ms for s in stalls
                    if (s.wall if wall else s.at) <= end and (s.wall if wall else s.at) + s.late_ms / 1000 >= since),
                   default=0.0)


_GAUGE = StarvationGauge()


def read_psi_some_us(path: str = PSI_CPU) -> int | None:
    """The host's cumulative CPU "some" stall (µs) from Linux PSI, or None where it cannot be read."""
    try:
        with open(path, encoding="ascii") as f:
            first = f.readline()
    except OSError:
        return None
    return parse_psi_total(first)


def parse_psi_total(line: str) -> int | None:
    """``some avg10=… total=N`` → N (None for any other line)."""
    if not line.startswith("some "):
        return None
    for field_ in line.split():
        if field_.startswith("total="):
            try:
                return int(field_[6:])
            except ValueError:
                return None
    return None


def is_loopback(host: str) -> bool:
    """A peer on this host: 127.0.0.0/8, ::1 or ::ffff:127.x (the only peers whose CPU the suite shares)."""
    try:
        addr = ipaddress.ip_address(host.strip("[]"))
    except ValueError:
        return host == "localhost"
    mapped = getattr(addr, "ipv4_mapped", None)
    return bool(addr.is_loopback or (mapped is not None and mapped.is_loopback))


def watch_loop(loop: asyncio.AbstractEventLoop, source: StarvationGauge | None = None,
               period_s: float = PERIOD_S) -> Callable[[], None]:
    """Measure an event loop's own lateness into the gauge (a callback every ``period_s``; a frame's time
    stamp there is when the loop got to it, so a loop kept busy or descheduled delays it). Returns stop()."""
    target = source or _GAUGE
    state: dict[str, Any] = {"due": time.monotonic() + period_s, "handle": None}

    def tick() -> None:
        now = time.monotonic()
        target.note(state["due"], (now - state["due"]) * 1000)
        state["due"] = now + period_s
        state["handle"] = loop.call_later(period_s, tick)

    state["handle"] = loop.call_later(period_s, tick)
    return lambda: state["handle"].cancel()


def gauge() -> StarvationGauge:
    """The process-wide gauge (start/stop it around timing work; it runs while anyone holds it)."""
    return _GAUGE


def explains(excess_ms: float, worst_ms: float) -> bool:
    """A stall of ``worst_ms`` could explain a timing breach of ``excess_ms`` beyond its limit."""
    return worst_ms >= NOISE_MS and worst_ms >= excess_ms


def host_starved_text(excess_ms: float, stall_ms: float, what: str) -> str:
    return (f"{STARVED_TEXT}: {what} exceeds its limit by {excess_ms:.1f} ms while the peer runs on this host "
            f"(a loopback address) and the host's CPU was contended around each breach (Linux PSI: some task waited "
            f"{stall_ms:.0f} ms for a CPU), which could have delayed the peer's sends; not judged")


def starved_text(excess_ms: float, worst_ms: float, what: str) -> str:
    return (f"{STARVED_TEXT}: {what} exceeds its limit by {excess_ms:.1f} ms, and the suite itself was kept from "
            f"running for up to {worst_ms:.1f} ms meanwhile (its timer woke that late), which could explain it; "
            "not judged")


def starved_share(windows: list[tuple[float, float]], excess_ms: float, source: StarvationGauge | None = None,
                  wall: bool = False) -> float:
    """The share of ``windows`` (start, end) that overlap a stall of at least ``excess_ms``: a median-type
    figure (a p50 latency) is explained only when at least half its samples could have been delayed so."""
    if not windows or excess_ms < NOISE_MS:
        return 0.0 if windows else 1.0
    gauge_ = source or _GAUGE
    return sum(1 for a, b in windows if gauge_.worst_ms(a, b, wall) >= excess_ms) / len(windows)


def starved_verdict(excess_ms: float, since: float, until: float | None = None, what: str = "the timing figure",
                    source: StarvationGauge | None = None, wall: bool = False) -> str | None:
    """The INCONCLUSIVE reason when the gauge's stalls in the range could explain a breach of ``excess_ms``
    (None: they could not, and the breach stands)."""
    worst = (source or _GAUGE).worst_ms(since, until, wall)
    return starved_text(excess_ms, worst, what) if explains(excess_ms, worst) else None


# -- kernel receive timestamps -----------------------------------------------------------------------


def enable_rx_timestamps(sock: socket.socket) -> bool:
    """Ask the kernel to stamp every received segment (False where it cannot)."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        return True
    except (OSError, AttributeError):
        return False


def recv_stamped(sock: socket.socket, size: int = 65536) -> tuple[bytes, float]:
    """``recv`` plus the kernel's receive time of the data, on the monotonic clock (now when no stamp came).

    Raises what ``recv`` raises. The stamp is CLOCK_REALTIME; it is moved to the monotonic clock by the
    offset between the two read now (the two clocks do not drift apart within a run)."""
    data, ancdata, _flags, _addr = sock.recvmsg(size, _ANC)
    for level, kind, payload in ancdata:
        if level == socket.SOL_SOCKET and kind == SCM_TIMESTAMPNS and len(payload) >= 16:
            sec, nsec = struct.unpack("qq", payload[:16])
            offset = time.time() - time.monotonic()
            return data, min(sec + nsec / 1e9 - offset, time.monotonic())
    return data, time.monotonic()
