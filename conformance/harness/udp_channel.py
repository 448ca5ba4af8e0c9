"""A recorded UDP socket talking to the box: one datagram, one frame (F7); re-exported by :mod:`.client`."""

from __future__ import annotations

import select
import socket
import time

from ..protocol import Frame, Profile, ProtocolError, TransferType, Transport, codec_for, decode_datagram
from .outcomes import Answer, Closed, Malformed, Outcome, Silence
from .target import Target, Unreachable, connect_failure
from .transcript import Endpoint, Kind, Transcript


class UdpChannel:
    """A recorded UDP socket talking to the box: one datagram, one frame (F7)."""

    def __init__(self, transcript: Transcript, target: Target, profile: Profile, label: str = "udp") -> None:
        self.transcript = transcript
        self.target = target
        self.profile = profile
        self.codec = codec_for(profile)
        self.time_out_s = profile.time_out_s
        family = socket.AF_INET6 if ":" in target.host else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        try:
            self.sock.connect((target.host, target.port))
        except OSError as exc:
            self.sock.close()
            raise Unreachable(f"cannot reach UDP target {target}: {connect_failure(exc, self.time_out_s)}") from None
        local, remote = self.sock.getsockname(), self.sock.getpeername()
        info = transcript.open("udp", Endpoint(local[0], local[1]), Endpoint(remote[0], remote[1]), label)
        self.conn_id = info.conn

    def send(self, data: bytes | Frame, note: str = "") -> None:
        if isinstance(data, Frame):
            data = self.codec.encode(data, Transport.UDP)
        try:
            self.sock.send(data)
        except OSError as exc:  # ICMP port unreachable from an earlier datagram, and the like
            self.transcript.note(f"send failed: {exc.strerror or exc}", self.conn_id)
        self.transcript.add(self.conn_id, Kind.SEND, data, note)

    def next_outcome(self, timeout_s: float | None = None, since: float | None = None) -> Outcome:
        start = since if since is not None else time.monotonic()
        deadline = time.monotonic() + (self.time_out_s if timeout_s is None else timeout_s)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return Silence(time.monotonic() - start)
            ready, _, _ = select.select([self.sock], [], [], remaining)
            if not ready:
                continue
            try:
                data = self.sock.recv(65536)
            except BlockingIOError:
                continue
            except OSError as exc:  # ECONNREFUSED: ICMP port unreachable
                self.transcript.note(f"recv failed: {exc.strerror or exc}", self.conn_id)
                return Closed(True, time.monotonic() - start)
            self.transcript.add(self.conn_id, Kind.RECV, data)
            latency = time.monotonic() - start
            try:
                return Answer(decode_datagram(data, self.profile, TransferType.BOX_TO_ROBOT), latency, data)
            except ProtocolError as exc:
                return Malformed(exc, latency)

    def receive(self, deadline: float, since: float | None = None) -> Outcome:
        """The next datagram's outcome by ``deadline`` (``time.monotonic()``), or silence."""
        return self.next_outcome(max(0.0, deadline - time.monotonic()), since)

    def request(self, data: bytes | Frame, note: str = "", timeout_s: float | None = None) -> Outcome:
        start = time.monotonic()
        self.send(data, note)
        return self.next_outcome(timeout_s, since=start)

    def close(self) -> None:
        self.sock.close()
