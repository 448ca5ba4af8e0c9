"""The independent boxes: variants as data, and the command line.

``python -m tests.impls.box --list`` lists them; ``python -m tests.impls.box VARIANT
--port 0`` serves one on 127.0.0.1 (first stdout line: ``listening tcp 127.0.0.1:PORT``,
plus `` udp 127.0.0.1:PORT`` when it serves UDP) until SIGTERM/SIGINT. In-process::

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
from .policy import DEFECTS, Choices
from .wire import Check


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


_STRICT_REQUESTS = Check(reject_request_error=True)
_CONFORMING = [
    Variant("resync-fine", Choices(framing="fine", malformed_cycle="silent"),
            "R6(b): only well-shaped request headers are trusted; a rejected header resumes the scan at its "
            "second byte. Malformed CycleOn/CycleOff and 26/27 are left unanswered; cycle state per box"),
    Variant("skip-header", Choices(framing="skip", malformed_ext="400", cycle_scope="connection",
                                   check=Check(ignore_check=False)),
            "R6(b'): a rejected header is skipped whole (12 bytes). TCP check must be 00 00 or the CRC (F6); "
            "malformed 26/27 get ResultCode 400; cycle state per connection"),
    Variant("trust-header", Choices(framing="trust", malformed_ext="400", udp=True),
            "R6(a): trusts a header with the right start word and version and a plausible length (like the "
            "reference, written independently); serves UDP too (R7: bad datagrams dropped)"),
    Variant("close-on-garbage", Choices(framing="close", on_not_request="close", malformed_cycle="silent"),
            "R6(c)/A5: closes the connection on any bytes that are not a request; malformed requests get "
            "their error codes"),
    Variant("byte-by-byte", Choices(framing="trust", writer="bytes"),
            "every answer written one byte per send(), with a 10 ms pause after the first byte"),
    Variant("strict-cycle", Choices(framing="fine", strict_cycle=True, cycle_scope="connection",
                                    check=_STRICT_REQUESTS),
            "S3: CycleOff without CycleOn -> 0002, CycleOn twice -> 0001, cycle state per connection; rejects "
            "requests whose error field is not 0000"),
    Variant("strict-cycle-box", Choices(framing="trust", strict_cycle=True, cycle_scope="box"),
            "S3: strict like strict-cycle, but one cycle state for the whole box (shared by all connections)"),
    Variant("unknown-error", Choices(framing="fine", on_not_request="error", malformed_ext="400"),
            "A5: a frame with the right start word that is not a request is answered with its action byte "
            "and error FFFF instead of silence"),
    Variant("nan-1001", Choices(framing="trust", check=Check(extension=False)),
            "B4: NaN/inf answered 1001/1002; no extension E (26/27 are unknown actions: silence)"),
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
}


def _broken(name: str) -> Variant:
    base_name, what = _BROKEN[name]
    base = _BASE[base_name]
    choices = replace(base.choices, udp=False).with_defect(name)
    return Variant(name, choices, f"{what} (built on {base_name}, TCP only)")


VARIANTS: dict[str, Variant] = {v.name: v for v in _CONFORMING} | {name: _broken(name) for name in _BROKEN}


def start_box(name: str, port: int = 0) -> ThreadBox:
    """A started box (use it as a context manager, or call ``stop()``)."""
    return ThreadBox(VARIANTS[name].choices, port=port).start()


def _list() -> str:
    lines = []
    for v in VARIANTS.values():
        kind = "conforming" if v.conforming else f"broken [{v.clause}]"
        lines.append(f"{v.name:<20} {kind:<18} {v.description}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.impls.box", description=__doc__.split("\n\n")[0])
    parser.add_argument("variant", nargs="?", help="which box (see --list)")
    parser.add_argument("--port", type=int, default=0, help="TCP port on 127.0.0.1 (0: a free one)")
    parser.add_argument("--list", action="store_true", help="list the variants and exit")
    args = parser.parse_args(argv)
    if args.list:
        print(_list())
        return 0
    if args.variant not in VARIANTS:
        print(f"error: unknown box {args.variant!r}; try --list", file=sys.stderr)
        return 2
    if not 0 <= args.port <= 65535:
        print("error: --port must be 0..65535", file=sys.stderr)
        return 2
    try:
        box = start_box(args.variant, args.port)
    except OSError as exc:
        print(f"error: cannot listen on 127.0.0.1:{args.port}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    stopping = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stopping.set())
    line = f"listening tcp 127.0.0.1:{box.port}"
    if box.udp_port is not None:
        line += f" udp 127.0.0.1:{box.udp_port}"
    print(line, flush=True)
    while not stopping.wait(0.5):
        pass
    box.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
