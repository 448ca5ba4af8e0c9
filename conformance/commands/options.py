"""Option helpers the command modules share: the profile group, the fuzzer's target options
and ``--listen`` parsing.

The profile options themselves are defined once in :mod:`conformance.runtime.profile_options`
(the pytest plugin adds the same ones); the suite's own options in
:mod:`conformance.runtime.settings`.
"""

from __future__ import annotations

import argparse
from typing import Any

from ..i18n import _
from ..runtime.profile_options import add_profile_options


def add_profile_group(p: argparse.ArgumentParser, title: str = "profile") -> None:
    """The profile options (``--crc`` ... ``--checking``) in their own ``--help`` group."""
    group = p.add_argument_group(title)
    add_profile_options(group.add_argument)


def add_target_options(p: argparse.ArgumentParser | Any) -> None:
    """``--target``, ``--udp-target`` and ``--extension`` as ``fuzz`` and ``replay`` take them."""
    p.add_argument("--target", metavar="HOST:PORT", help=_("the AI Box over TCP (default: start the bundled reference box)"))
    p.add_argument("--udp-target", metavar="HOST:PORT", help=_("the box's UDP endpoint (UDP cases only with it; "
                   "the bundled box's UDP port when no --target is given)"))
    p.add_argument("--extension", choices=("auto", "on", "off"), default="auto",
                   help=_("extension E (actions 26/27): detect (auto, default), or force on/off"))


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` or ``[V6]:PORT`` (port 0 picks a free one); ValueError if malformed."""
    text = text.strip()
    if text.startswith("["):
        host, sep, rest = text[1:].partition("]")
        if not sep or not rest.startswith(":"):
            raise ValueError(f"bad --listen {text!r}; expected [IPv6]:PORT")
        port_text = rest[1:]
    elif text.count(":") == 1:
        host, port_text = text.split(":")
    else:
        raise ValueError(f"bad --listen {text!r}; expected HOST:PORT (e.g. 0.0.0.0:9004)")
    if not host:
        raise ValueError(f"bad --listen {text!r}: no host")
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"bad port in --listen {text!r}") from None
    if not 0 <= port <= 65535:
        raise ValueError(f"port out of range in --listen {text!r}")
    return host, port
