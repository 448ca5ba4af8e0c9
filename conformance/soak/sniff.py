"""A small packet sniffer for the soak's pcap ring: one AF_PACKET socket on the loopback (or another)
interface, a classic BPF program for ``tcp port P`` attached in the kernel, kernel receive time stamps
(``SO_TIMESTAMPNS``), and the output file switched at every window boundary without a gap.

The BPF program is compiled here, by hand (it is tcpdump's ``-dd`` output for ``tcp port P`` on an
Ethernet link: IPv4 with the IP header's length, unfragmented, and IPv6), so neither libpcap nor scapy
is needed. On the loopback interface Linux shows every packet twice (going out, coming in): the
outgoing copy is dropped, as libpcap does. Needs root or CAP_NET_RAW: :class:`SniffError` otherwise.
"""

from __future__ import annotations

import contextlib
import ctypes
import select
import socket
import struct
import threading
import time
from pathlib import Path

from ..evidence.pcapng import LINKTYPE_ETHERNET, PcapNgFile

SO_ATTACH_FILTER = 26
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)
ETH_P_ALL = 0x0003
PACKET_OUTGOING = 4
SNAPLEN = 262144
_ANC = socket.CMSG_SPACE(16)


class SniffError(RuntimeError):
    """The sniffer cannot start (no permission, no such interface, not Linux)."""


def tcp_port_program(port: int) -> list[tuple[int, int, int, int]]:
    """``tcp port PORT`` as classic BPF (code, jt, jf, k), jumps relative, as ``tcpdump -dd`` prints it."""
    absolute = [  # (code, k, true target, false target): targets absolute, as ``tcpdump -d`` prints them
        (0x28, 12, None, None), (0x15, 0x86DD, 2, 8), (0x30, 20, None, None), (0x15, 6, 4, 19),
        (0x28, 54, None, None), (0x15, port, 18, 6), (0x28, 56, None, None), (0x15, port, 18, 19),
        (0x15, 0x0800, 9, 19), (0x30, 23, None, None), (0x15, 6, 11, 19), (0x28, 20, None, None),
        (0x45, 0x1FFF, 19, 13), (0xB1, 14, None, None), (0x48, 14, None, None), (0x15, port, 18, 16),
        (0x48, 16, None, None), (0x15, port, 18, 19), (0x06, SNAPLEN, None, None), (0x06, 0, None, None),
    ]
    out = []
    for i, (code, k, jt, jf) in enumerate(absolute):
        out.append((code, 0 if jt is None else jt - i - 1, 0 if jf is None else jf - i - 1, k))
    return out


def _attach(sock: socket.socket, program: list[tuple[int, int, int, int]]) -> None:
    raw = b"".join(struct.pack("HBBI", *insn) for insn in program)
    buf = ctypes.create_string_buffer(raw)
    fprog = struct.pack("HL", len(program), ctypes.addressof(buf))
    sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER, fprog)


class Sniffer:
    """Packets of ``tcp port PORT`` on ``interface`` into the current file (``switch`` changes it)."""

    def __init__(self, port: int, interface: str = "lo") -> None:
        family = getattr(socket, "AF_PACKET", None)
        if family is None:
            raise SniffError("live pcaps need Linux (AF_PACKET)")
        try:
            sock = socket.socket(family, socket.SOCK_RAW, 0)  # protocol 0: nothing arrives before the filter
        except PermissionError as exc:
            raise SniffError(f"live pcaps need root or CAP_NET_RAW: {exc}") from None
        try:
            _attach(sock, tcp_port_program(port))
            sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
            sock.bind((interface, ETH_P_ALL))  # Python puts the protocol in network order itself
        except OSError as exc:
            sock.close()
            raise SniffError(f"live pcaps on {interface!r}: {exc.strerror or exc}") from None
        self.sock = sock
        self.interface = interface
        self.port = port
        self.loopback = interface == "lo"
        self.packets = 0
        self.error: OSError | None = None
        self._out: PcapNgFile | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="isight-soak-sniffer", daemon=True)
        self._thread.start()

    def switch(self, path: Path | None, comment: str = "") -> int:
        """Close the current file (its packet count is returned) and write into ``path`` from now on."""
        with self._lock:
            count = 0
            if self._out is not None:
                count = self._out.packets
                self._out.close()
                self._out = None
            if path is not None:
                try:
                    out = PcapNgFile(path, application="isight-conformance soak", comment=comment)
                    out.add_interface(LINKTYPE_ETHERNET, self.interface, f"filter: tcp port {self.port}")
                    self._out = out
                except OSError as exc:
                    self.error = exc
            return count

    def _run(self) -> None:
        sock = self.sock
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([sock], [], [], 0.2)
                if not ready:
                    continue
                data, ancdata, _flags, addr = sock.recvmsg(SNAPLEN, _ANC)
            except OSError as exc:
                self.error = exc
                return
            if self.loopback and addr[2] == PACKET_OUTGOING:
                continue  # the same packet arrives again as incoming
            stamp = time.time()
            for level, kind, payload in ancdata:
                if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and len(payload) >= 16:
                    sec, nsec = struct.unpack("qq", payload[:16])
                    stamp = sec + nsec / 1e9
            with self._lock:
                if self._out is not None:
                    self._out.write_packet(data, stamp)
                    self.packets += 1

    def close(self) -> int:
        self._stop.set()
        self._thread.join(2.0)
        count = self.switch(None)
        self.sock.close()
        return count


__all__ = ["SniffError", "Sniffer", "tcp_port_program"]
