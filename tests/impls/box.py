"""The independent boxes: variants as data, and the command line.

``python -m tests.impls.box --list`` lists them; ``python -m tests.impls.box VARIANT
--port 0`` serves one on 127.0.0.1 (first stdout line: ``listening tcp 127.0.0.1:PORT``,
plus `` udp 127.0.0.1:PORT`` when it serves UDP, `` stream 127.0.0.1:PORT`` when the
stream has its own port, and `` args FLAG ...`` with the profile flags a tester needs)
until SIGTERM/SIGINT. ``python -m tests.impls.box random --seed N`` serves a random legal
combination of the knobs (:data:`tests.impls.policy.KNOBS`, one per row of the legal
table); ``python -m tests.impls.box BROKEN --seed N`` a broken box on a random legal
base. In-process::

    with start_box("resync-fine") as box:
        socket.create_connection(("127.0.0.1", box.port))

Conforming boxes each make their own legal choices (PROTOCOL.md R6, A5, A3, S3, F6,
E); a broken box is a conforming one with exactly one switch flipped (``defect``).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from dataclasses import dataclass, replace

from .boxcore import ThreadBox
from .framers import PRESETS
from .policy import DEFECTS, Choices, knob_choices, random_choices, with_framing


@dataclass(frozen=True)
class Variant:
    name: str
    choices: Choices
    description: str

    @property
    def conforming(self) -> bool:
        return self.choices.defect is None

    @property
    def clause(self) -> str | None:
        """The clause a broken box's defect breaks (None when conforming)."""
        return DEFECTS[self.choices.defect] if self.choices.defect else None


def _preset(framing: str, **knobs: str) -> Choices:
    return with_framing(knob_choices(knobs), PRESETS[framing])


_CONFORMING = [
    Variant("resync-fine", _preset("fine", malformed_blockless="silent"),
            "R6(b): only well-shaped request headers are trusted; a rejected header resumes the scan at its "
            "second byte. Malformed 00/01/02 and 26/27 are left unanswered; cycle state per box"),
    Variant("skip-header", _preset("skip", malformed_ext="400", cycle_scope="connection", tcp_check="zero-or-crc"),
            "R6(b'): a rejected header is skipped whole (12 bytes). TCP check must be 00 00 or the CRC (F6); "
            "malformed 26/27 get ResultCode 400; cycle state per connection"),
    Variant("trust-header", _preset("trust", malformed_ext="400", udp="on"),
            "R6(a): trusts a header with the right start word and version and a plausible length (like the "
            "reference, written independently); serves UDP too (R7: bad datagrams dropped)"),
    Variant("close-on-garbage", _preset("close", not_request="close", malformed_blockless="silent"),
            "R6(c)/A5: closes the connection on any bytes that are not a request; malformed requests get "
            "their error codes"),
    Variant("byte-by-byte", _preset("trust", writer="bytes"),
            "every answer written one byte per send(), with a 10 ms pause after the first byte"),
    Variant("strict-cycle", _preset("fine", cycle_on_twice="0001", cycle_off_idle="0002", cycle_scope="connection",
                                    request_error_field="reject"),
            "S3: CycleOff without CycleOn -> 0002, CycleOn twice -> 0001, cycle state per connection; rejects "
            "requests whose error field is not 0000"),
    Variant("strict-cycle-box", _preset("trust", cycle_on_twice="0001", cycle_off_idle="0002", cycle_scope="box"),
            "S3: strict like strict-cycle, but one cycle state for the whole box (shared by all connections)"),
    Variant("unknown-error", _preset("fine", not_request="error", malformed_ext="400"),
            "A5: a frame with the right start word that is not a request is answered with its action byte "
            "and error FFFF instead of silence"),
    Variant("nan-1001", _preset("trust", extension="absent"),
            "B4: NaN/inf answered 1001/1002; no extension E (26/27 are unknown actions: silence)"),
    Variant("completes-short", replace(_preset("fine"), short_frames=True),
            "R6(b): a header with another version that announces no blocks is rejected once its check field is "
            "read: 12 bytes take the next request's first two bytes as their check field (that request is lost; "
            "the next one is answered)"),
    Variant("late-inside-timeout", replace(_preset("trust"), late=0.02),
            "T1: every answer a fiftieth of time_out late (100 ms at the default), inside it"),
    Variant("slow-pieces", _preset("trust", latency="20ms", writer="pieces"),
            "T1: every answer 20 ms late, written in two pieces with Nagle on (the header, then the rest)"),
    Variant("slow-cycle-on", _preset("trust", cycle_on_latency="0.6 time_out"),
            "T1: CycleOn answered after 0.6 time_out (the detection takes that long to start), inside time_out"),
]

_BASE = {v.name: v for v in _CONFORMING}
#: broken variant -> (the conforming variant it is built on, what it does)
_BROKEN: dict[str, tuple[str, str]] = {
    "swapped-version": ("trust-header", "every answer carries version 01 00"),
    "swapped-error": ("trust-header", "the error code bytes of every answer are swapped (1001 -> 01 10)"),
    "wrong-transfer-type": ("trust-header", "every answer carries transfer type 01"),
    "zero-to-malformed": ("trust-header", "malformed pose requests (bad length/index/NaN) are answered 0000"),
    "one-at-a-time": ("trust-header", "serves one connection at a time; the next waits until the first closes"),
    "leaky": ("trust-header", "never closes or frees a connection; resets every connection after the 64th"),
    "dead": ("trust-header", "accepts connections, reads and never answers"),
    "slow-bytes": ("trust-header", "writes each answer one byte every 0.5 s"),
    "late-cycle-on": ("trust-header", "answers CycleOn after 6 s (time_out is 5 s)"),
    "flood-random": ("trust-header", "after accepting, writes random bytes as fast as the peer reads, forever"),
    "flood-headers": ("trust-header", "writes endless FE FE 00 01 10 23 01 FF FF FF 00 00 headers (255 x 65535)"),
    "no-resync": ("trust-header", "after garbage (or any frame that is not a request) it hangs silently"),
    "nan-zero": ("trust-header", "NaN/inf in a pose or tolerance answered 0000"),
    "drops-coalesced": ("trust-header", "answers only the first of several frames that arrive in one read"),
    "sticky-error": ("trust-header", "after any error answer, every later answer on the connection carries that "
                                     "error code (a C struct never cleared)"),
    "drops-frames": ("trust-header", "every 7th answer on a connection is never written"),
    "answers-some-actions": ("trust-header", "never answers Tolerance (25) or RegisterPose (24)"),
    "quiet-after-n": ("trust-header", "after 150 answers in all it answers nothing more (it still accepts and reads)"),
    "short-send-drops": ("trust-header", "a small send buffer and one non-blocking send() per answer: what did not "
                                         "fit is dropped"),
    "latency-grows": ("trust-header", "each answer on a connection 2 ms later than the one before (a backlog)"),
    "drops-unsendable": ("trust-header", "one non-blocking send() per answer with the kernel's default buffers: an "
                                         "answer the kernel cannot take at once (EAGAIN, or a part) is dropped"),
    "low-byte-length": ("trust-header", "reads the block length from its low byte only (L = 0x0119 taken as 25)"),

    "drops-rest-of-read": ("trust-header", "handles the first whole frame of each read and discards the rest of the "
                                           "read (answered or not: a frame that is not a request is consumed too)"),
    "split-header-lost": ("trust-header", "expects a frame's 12-byte header in one read: a read of fewer than 12 "
                                          "bytes at the start of a frame is discarded"),

    "stall-once": ("trust-header", "once, past its 40th frame and on a connection in use, its whole loop blocks "
                                   "for 6 s: no connection is answered, fresh ones included"),
    "udp-crc-ccitt": ("trust-header", "signs and checks UDP frames with CRC-16/CCITT-FALSE, not MODBUS"),
    "udp-no-crc-check": ("trust-header", "never checks the CRC of a UDP request (signs its answers right)"),
    "udp-crc-header": ("trust-header", "the UDP CRC covers the 12-byte header only, not the blocks"),
    "udp-answer-port": ("trust-header", "sends each UDP answer to the request's source port + 1"),
    "udp-two-frames": ("trust-header", "takes every frame of a UDP datagram and answers each"),
    "tcp-check-crc": ("trust-header", "writes the CRC-16/MODBUS of each TCP answer in its check field"),
    "tcp-crc-refused": ("trust-header", "refuses a TCP request whose check field holds its CRC (accepts only 00 00)"),
}
#: knobs a random base keeps fixed under a defect, so that the defect stays what it is planted to be
_BASE_FIXED: dict[str, dict[str, str]] = {
    "one-at-a-time": {"stream_port": "same"},  # a second listener would serve a second connection at once
    "no-resync": {"framing_garbage": "scan", "not_request": "silent", "ext_refusal": "silent",
                  "framing_version": "resume+1"},  # it hangs where a conforming box resynchronises, not closes
    "late-cycle-on": {"cycle_on_ready": "ready"},  # the late answer is a 0000 the suite waits for
    "nan-zero": {"nan": "accept"},
    # one send() per answer, as planted: a writer in pieces or bytes (a pause per answer) is too slow to back up
    "drops-unsendable": {"writer": "whole"},
}
#: knobs every run of the suite (the matrix) can serve: TCP only, one port
_BROKEN_FIXED = {"udp": "off", "stream_port": "same"}
#: defects that are about UDP: their boxes serve it (the matrix passes --udp-target)
_UDP = ("udp-crc-ccitt", "udp-no-crc-check", "udp-crc-header", "udp-answer-port", "udp-two-frames")


def _broken(name: str, base_seed: int | None = None) -> Variant:
    """A broken box: the defect on its documented base, or (``base_seed``) on a random legal one."""
    base_name, what = _BROKEN[name]
    udp = "on" if name in _UDP else "off"
    if base_seed is None:
        choices = replace(_BASE[base_name].choices, udp=udp).with_defect(name)
        return Variant(name, choices, f"{what} (built on {base_name}, {'UDP too' if udp == 'on' else 'TCP only'})")
    fixed = _BROKEN_FIXED | _BASE_FIXED.get(name, {}) | {"udp": udp}
    choices = random_choices(base_seed, fixed=fixed).with_defect(name)
    return Variant(name, choices, f"{what} (built on random base {base_seed}, TCP only)")


VARIANTS: dict[str, Variant] = {v.name: v for v in _CONFORMING} | {name: _broken(name) for name in _BROKEN}
RANDOM = "random"


def variant(name: str, seed: int | None = None) -> Variant:
    """A box by name; ``random`` (with ``seed``) is a random legal combination, a broken box with ``seed``
    sits on a random legal base."""
    if name == RANDOM:
        if seed is None:
            raise ValueError("the random box needs --seed")
        choices = random_choices(seed)
        return Variant(f"random#{seed}", choices, "a random legal combination: " + describe(choices))
    if name in _BROKEN and seed is not None:
        return _broken(name, seed)
    return VARIANTS[name]


def describe(choices: Choices) -> str:
    """The knobs that differ from the defaults, ``knob=value`` (the defaults otherwise)."""
    default = Choices()
    diff = [f"{k}={v}" for k, v in choices.knobs().items() if getattr(default, k) != v]
    return " ".join(diff) or "the defaults"


def start_box(name: str, port: int = 0, seed: int | None = None) -> ThreadBox:
    """A started box (use it as a context manager, or call ``stop()``)."""
    return ThreadBox(variant(name, seed).choices, port=port).start()


def _list() -> str:
    lines = []
    for v in VARIANTS.values():
        kind = "conforming" if v.conforming else f"broken [{v.clause}]"
        lines.append(f"{v.name:<20} {kind:<18} {v.description}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.impls.box", description=__doc__.split("\n\n")[0])
    parser.add_argument("variant", nargs="?", help="which box (see --list), or 'random'")
    parser.add_argument("--port", type=int, default=0, help="TCP port on 127.0.0.1 (0: a free one)")
    parser.add_argument("--seed", type=int, help="random: the combination; a broken box: its random legal base")
    parser.add_argument("--time-out", type=int, default=5000, metavar="MS", help="the time_out the box assumes")
    parser.add_argument("--for-robot", action="store_true",
                        help="serve a robot of tests/impls whatever the combination says: the stream on the command "
                             "port (the robot is wired to one address, e.g. through isight-conformance monitor) and "
                             "data block indexes from 0 (the robot's profile)")
    parser.add_argument("--list", action="store_true", help="list the variants and exit")
    args = parser.parse_args(argv)
    if args.list:
        print(_list())
        return 0
    try:
        if args.variant not in VARIANTS and args.variant != RANDOM:
            raise ValueError(f"unknown box {args.variant!r}; try --list")
        if not 0 <= args.port <= 65535 or not 0 < args.time_out <= 600_000:
            raise ValueError("--port must be 0..65535 and --time-out 1..600000")
        chosen = variant(args.variant, args.seed)
        if args.for_robot:
            chosen = replace(chosen, choices=replace(chosen.choices, stream_port="same", first_index="0"))
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        box = ThreadBox(replace(chosen.choices, time_out=args.time_out / 1000), port=args.port).start()
    except OSError as exc:
        print(f"error: cannot listen on 127.0.0.1:{args.port}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    stopping = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stopping.set())
    print(listening_line(box), flush=True)
    while not stopping.wait(0.5):
        pass
    box.stop()
    return 0


def listening_line(box: ThreadBox) -> str:
    line = f"listening tcp 127.0.0.1:{box.port}"
    if box.udp_port is not None:
        line += f" udp 127.0.0.1:{box.udp_port}"
    if box.stream_port is not None:
        line += f" stream 127.0.0.1:{box.stream_port}"
    flags = box.choices.suite_args()
    return line + (" args " + " ".join(flags) if flags else "")


if __name__ == "__main__":
    sys.exit(main())
