"""Profile settings as command-line options, defined once.

Both the CLI (argparse) and the pytest plugin (``parser.addoption``, which takes
the same keyword arguments) add these, and :func:`profile_from_options` is the one
place where values become a :class:`~conformance.protocol.Profile`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from ..i18n import N_, gettext
from ..protocol import DEFAULT_PROFILE, Profile, TcpCheckPolicy, crc16_names


@dataclass(frozen=True)
class Option:
    flag: str  # e.g. "--crc"
    field: str  # Profile field
    help: str
    type: Callable[[str], Any] = str
    choices: tuple[Any, ...] | None = None
    metavar: str | None = None
    shown_default: str | None = None  # how --help shows the default, when not str(default)

    @property
    def dest(self) -> str:
        return "profile_" + self.field

    def kwargs(self) -> dict[str, Any]:
        default = getattr(DEFAULT_PROFILE, self.field)
        if isinstance(default, TcpCheckPolicy):
            default = default.value
        out: dict[str, Any] = {
            "dest": self.dest,
            "default": None,
            "help": gettext("{help} (default: {default})").format(help=gettext(self.help),
                                                                  default=self.shown_default or default),
        }
        if self.type is not str:
            out["type"] = self.type
        if self.choices:
            out["choices"] = list(self.choices)
        if self.metavar:
            out["metavar"] = self.metavar
        return out


def _bool(text: str) -> bool:
    value = text.strip().lower()
    if value in ("1", "true", "yes", "on", "strict"):
        return True
    if value in ("0", "false", "no", "off", "lenient"):
        return False
    raise ValueError(f"expected strict/lenient or true/false, not {text!r}")


PROFILE_OPTIONS: tuple[Option, ...] = (
    Option("--crc", "crc", N_("[F7] CRC-16 algorithm for UDP (any crcmod predefined 16-bit name)"),
           choices=crc16_names(), metavar="NAME"),
    Option("--crc-byte-order", "crc_byte_order", N_("[F7] byte order of the UDP CRC"), choices=("big", "little")),
    Option("--first-index", "first_index", N_("[B3] index of the first data block"), type=int, choices=(0, 1)),
    Option("--tcp-check", "tcp_check", N_("[F6] what a TCP receiver accepts in the check field"),
           choices=tuple(p.value for p in TcpCheckPolicy)),
    Option("--byte-order", "byte_order", N_("[F4] byte order of multi-byte header fields"), choices=("big", "little")),
    Option("--float-byte-order", "float_byte_order", N_("[B4/E1] byte order of float32/int32 block values"),
           choices=("big", "little")),
    Option("--time-out", "time_out_ms", N_("[T1] time_out in ms: bound on connect and every answer"), type=int,
           metavar="MS"),
    Option("--vision-time-out", "vision_time_out_ms", N_("[E3] vision_time_out in ms for the result request"),
           type=int, metavar="MS"),
    Option("--pose-rate", "pose_rate_hz", N_("[T2] pose stream rate in Hz"), type=float, metavar="HZ"),
    Option("--progidx-conflict", "progidx_conflict", N_("[E2] where a ProgIdx 409 travels"),
           choices=("block", "error-code")),
    Option("--checking", "strict", N_("strict also enforces SHOULD rules (B4: no NaN or infinity); lenient accepts them, and "
           "a first block index of 0 or 1 (B3)"),
           type=_bool, metavar="strict|lenient", shown_default="strict"),
)


def add_profile_options(add: Callable[..., Any]) -> None:
    """Register every profile option with ``add`` (argparse's or pytest's addoption)."""
    for opt in PROFILE_OPTIONS:
        add(opt.flag, **opt.kwargs())


def profile_from_options(values: Mapping[str, Any] | Callable[[str], Any] | Any, base: Profile = DEFAULT_PROFILE) -> Profile:
    """Build the profile from parsed options: a mapping, a ``get(dest)`` function, or
    an argparse Namespace. Options left unset keep ``base``'s value. Raises ValueError
    with a clear message."""
    get: Callable[[str], Any]
    if isinstance(values, Mapping):
        get = values.get
    elif callable(values):
        get = values
    else:
        def get(key: str) -> Any:
            return getattr(values, key, None)

    changes = {opt.field: get(opt.dest) for opt in PROFILE_OPTIONS if get(opt.dest) is not None}
    return base.replace(**changes) if changes else base


def profile_flags(profile: Profile) -> list[str]:
    """The command-line flags that reproduce ``profile`` (for 'rerun with' hints)."""
    flags = []
    diff = profile.differences()
    for opt in PROFILE_OPTIONS:
        if opt.field in diff:
            value = diff[opt.field]
            if opt.field == "strict":
                value = "strict" if value else "lenient"
            flags.append(f"{opt.flag}={value}")
    return flags
