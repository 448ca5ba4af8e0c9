"""``HOST:PORT`` targets and the one clear error when they cannot be reached."""

from __future__ import annotations

import socket
from collections.abc import Callable
from dataclasses import dataclass


class Unreachable(Exception):
    """The target refused, timed out, or does not resolve; str() is one clear line."""


class Refused(Unreachable):
    """The target refused the connection (nothing listens there, or a full accept queue)."""


@dataclass(frozen=True)
class Target:
    host: str
    port: int

    @classmethod
    def parse(cls, text: str, default_port: int | None = None) -> Target:
        """``10.0.0.5:9000``, ``[::1]:9004``, ``localhost:9004`` (or a bare host with a default port)."""
        text = text.strip()
        if not text:
            raise ValueError("empty target; expected HOST:PORT")
        has_port = True
        if text.startswith("["):
            host, sep, rest = text[1:].partition("]")
            if not sep:
                raise ValueError(f"bad target {text!r}: missing ']'")
            if rest and not rest.startswith(":"):
                raise ValueError(f"bad target {text!r}: expected [IPv6]:PORT")
            has_port, port_text = bool(rest), rest[1:]
        elif text.count(":") == 1:
            host, _, port_text = text.partition(":")
        elif text.count(":") > 1:
            raise ValueError(f"bad target {text!r}: write IPv6 addresses as [ADDR]:PORT")
        else:
            host, port_text, has_port = text, "", False
        if has_port and not port_text:
            raise ValueError(f"bad target {text!r}: no port after ':'")
        if not has_port:
            if default_port is None:
                raise ValueError(f"bad target {text!r}: expected HOST:PORT")
            return cls(host, default_port)
        try:
            port = int(port_text)
        except ValueError:
            raise ValueError(f"bad target {text!r}: port {port_text!r} is not a number") from None
        if not 0 < port < 65536:
            raise ValueError(f"bad target {text!r}: port {port} is out of range 1-65535")
        if not host:
            raise ValueError(f"bad target {text!r}: no host")
        return cls(host, port)

    def __str__(self) -> str:
        return f"[{self.host}]:{self.port}" if ":" in self.host else f"{self.host}:{self.port}"


def check_reachable(target: Target, time_out_s: float) -> str | None:
    """None when a TCP connection opens within time_out, else one line saying why not."""
    try:
        with socket.create_connection((target.host, target.port), timeout=time_out_s):
            return None
    except ConnectionRefusedError:
        return f"target {target} unreachable: connection refused (nothing listens on that port)"
    except TimeoutError:
        return f"target {target} unreachable: no answer to the connection request within {time_out_s * 1000:.0f} ms"
    except socket.gaierror as exc:
        return f"target {target} unreachable: host name does not resolve ({exc.strerror})"
    except (ConnectionResetError, BrokenPipeError):
        return None  # something listens there and reset us: it is reachable; the cases judge the rest
    except OSError as exc:
        return f"target {target} unreachable: {exc.strerror or exc}"


def dial(target: Target, time_out_s: float, prepare: Callable[[socket.socket], None] | None) -> socket.socket:
    """``socket.create_connection``, with ``prepare`` applied to the socket before it connects."""
    if prepare is None:
        return socket.create_connection((target.host, target.port), timeout=time_out_s)
    error: OSError = OSError(f"{target.host} does not resolve")
    for family, kind, proto, _, addr in socket.getaddrinfo(target.host, target.port, type=socket.SOCK_STREAM):
        sock = socket.socket(family, kind, proto)
        try:
            prepare(sock)
            sock.settimeout(time_out_s)
            sock.connect(addr)
            return sock
        except OSError as exc:
            sock.close()
            error = exc
    raise error


def connect_failure(exc: OSError, time_out_s: float) -> str:
    """One line: why a connection attempt failed."""
    if isinstance(exc, (TimeoutError, socket.timeout)):
        return f"no answer to the connection request within time_out ({time_out_s * 1000:.0f} ms)"
    if isinstance(exc, ConnectionRefusedError):
        return "connection refused (nothing listens on that port)"
    if isinstance(exc, socket.gaierror):
        return f"host name does not resolve ({exc.strerror})"
    return exc.strerror or str(exc)
