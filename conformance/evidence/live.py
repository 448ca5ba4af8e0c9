"""``--capture live``: a real packet capture around a case, written as pcapng.

Where :mod:`conformance.evidence.pcap` draws the packets a transcript implies, this
records what the kernel actually put on an interface (retransmissions, window
updates, the box's real segmentation), with scapy's ``AsyncSniffer``::

    with LiveCapture("out/F1-001.live.pcapng", interface="lo", port=9004, case_id="F1-001"):
        run_case()

It needs a raw packet socket: root or CAP_NET_RAW (``setcap cap_net_raw+ep`` on the
Python binary). Without it :meth:`LiveCapture.start` raises :class:`CaptureError`
right away, before the case runs.

Details that a plain ``sniff(iface="lo")`` gets wrong, handled here:

* On a loopback interface Linux shows every packet twice (going out and coming in);
  the outgoing copy is dropped, as libpcap does.
* scapy does not know the loopback device type (ARPHRD_LOOPBACK); its frames are
  Ethernet with zero MACs and are written as such.
* The socket's receive buffer is raised (a burst of 64 KiB loopback segments
  overflows scapy's default), and packets still queued when :meth:`LiveCapture.stop`
  is called are drained into the file, not dropped.

Packets are written as they arrive with the kernel's time stamps, each in one
write to an unbuffered file (:class:`~conformance.evidence.pcapng.PcapNgFile`), so an
interrupted run leaves a readable file.
"""

from __future__ import annotations

import errno
import os
import select
import socket
import threading
from pathlib import Path
from typing import Any

from conformance.evidence.pcapng import PcapNgFile
from conformance.protocol.constants import DEFAULT_PORT

__all__ = ["CaptureError", "LiveCapture", "default_bpf"]

#: Most packets read from the socket by :meth:`LiveCapture.stop` after the sniffer ends.
_DRAIN_LIMIT = 100_000
_RCVBUF = 32 << 20
_SNAPLEN = 262144
_ARPHRD_ETHER, _ARPHRD_LOOPBACK = 1, 772
_LINKTYPE_ETHERNET, _LINKTYPE_RAW = 1, 101
_PACKET_OUTGOING = 4
_SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)


class CaptureError(RuntimeError):
    """A live capture cannot be started (privileges, interface, filter)."""


def default_bpf(port: int = DEFAULT_PORT) -> str:
    return f"tcp port {port} or udp port {port}"


def _open_socket(interface: str, bpf: str) -> Any:
    """A listening PF_PACKET socket on ``interface`` with ``bpf`` attached, returning
    raw frames (tests replace this function)."""
    import scapy.arch  # noqa: F401 - sets conf.L2listen for this platform
    from scapy.config import conf

    base: Any = conf.L2listen
    if base is None:
        raise CaptureError("live capture is not supported on this platform (scapy has no L2 listen socket)")
    if not hasattr(base, "_recv_raw"):  # not Linux PF_PACKET (e.g. BSD /dev/bpf): scapy's socket as is
        sock = base(iface=interface, filter=bpf)
        sock.linktype = conf.l2types.layer2num.get(sock.LL, _LINKTYPE_ETHERNET)
        sock.LL = conf.raw_layer
        return sock

    class _ListenSocket(base):
        LL: Any  # scapy's link layer class for this interface (replaced by Raw below)

        def __init__(self) -> None:
            super().__init__(iface=interface, nofilter=1)
            try:
                _attach_filter(self.ins, bpf, interface)
            except BaseException:
                self.close()
                raise
            family = self.ins.getsockname()[3]
            self.loopback = family == _ARPHRD_LOOPBACK
            if self.lvl == 3:
                self.linktype = _LINKTYPE_RAW
            elif family in (_ARPHRD_ETHER, _ARPHRD_LOOPBACK):
                self.linktype = _LINKTYPE_ETHERNET
            else:
                self.linktype = conf.l2types.layer2num.get(self.LL, _LINKTYPE_ETHERNET)
            self.LL = conf.raw_layer  # keep the bytes; no dissection in the capture thread
            for opt in (_SO_RCVBUFFORCE, socket.SO_RCVBUF):
                try:
                    self.ins.setsockopt(socket.SOL_SOCKET, opt, _RCVBUF)
                    break
                except OSError:
                    continue

        def recv_raw(self, x: int = 65535) -> tuple[Any, Any, Any]:
            pkt, sa_ll, ts = self._recv_raw(self.ins, max(x, _SNAPLEN))
            if self.loopback and sa_ll[2] == _PACKET_OUTGOING:
                return None, None, None  # the same packet arrives again as incoming
            if ts is None:
                from scapy.arch.linux import get_last_packet_timestamp

                ts = get_last_packet_timestamp(self.ins)
            return self.LL, pkt, ts

    return _ListenSocket()


def _attach_filter(sock: socket.socket, bpf: str, interface: str) -> None:
    """Attach ``bpf`` like scapy does, but with a snap length of 256 KiB: scapy compiles
    with a snap length of 65535, which cuts loopback frames (up to 65550 bytes) short."""
    from scapy.arch.common import compile_filter, free_filter
    from scapy.arch.linux import _flush_fd
    from scapy.data import SO_ATTACH_FILTER
    from scapy.libs.structures import sock_fprog

    program = compile_filter(bpf, interface)
    try:
        for i in range(program.bf_len):
            insn = program.bf_insns[i]
            if insn.code == 0x06 and insn.k > 0:  # BPF_RET|BPF_K accepting a packet: its snap length
                insn.k = _SNAPLEN
        sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER, sock_fprog(program.bf_len, program.bf_insns))
    finally:
        free_filter(program)
    _flush_fd(sock.fileno())  # what arrived before the filter was attached


def _is_permission_error(exc: BaseException) -> bool:
    return isinstance(exc, PermissionError) or (isinstance(exc, OSError) and exc.errno in (errno.EPERM, errno.EACCES))


class LiveCapture:
    """Capture ``interface`` (default ``lo``) filtered by ``bpf`` into a pcapng at ``path``.

    ``bpf`` defaults to ``"tcp port P or udp port P"`` for ``port`` (9004). Use as a
    context manager or call :meth:`start` / :meth:`stop`. :attr:`packets` counts what
    was written; :attr:`error` holds an exception the capture ended with.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        interface: str = "lo",
        bpf: str | None = None,
        *,
        port: int = DEFAULT_PORT,
        case_id: str = "",
    ) -> None:
        self.path = Path(path)
        self.interface = interface
        self.bpf = bpf if bpf is not None else default_bpf(port)
        self.case_id = case_id
        self.error: BaseException | None = None
        self._sock: Any = None
        self._sniffer: Any = None
        self._out: PcapNgFile | None = None
        self._packets = 0
        self._lock = threading.Lock()

    @property
    def packets(self) -> int:
        """Packets written so far."""
        return self._out.packets if self._out is not None else self._packets

    # -- lifecycle ---------------------------------------------------------------------
    def start(self) -> LiveCapture:
        if self._sniffer is not None:
            raise CaptureError("live capture already started")
        try:
            sock = _open_socket(self.interface, self.bpf)
        except (KeyboardInterrupt, SystemExit, CaptureError):
            raise
        except BaseException as exc:  # scapy raises a variety of types here
            if _is_permission_error(exc):
                raise CaptureError(
                    f"live capture needs root or CAP_NET_RAW: {exc} "
                    "(run as root, `setcap cap_net_raw+ep` the Python binary, or use the synthesised pcap)"
                ) from exc
            if (isinstance(exc, OSError) and exc.errno in (errno.ENODEV, errno.ENXIO)) or (
                isinstance(exc, ValueError) and "not found" in str(exc)  # scapy: "Interface 'x' not found !"
            ):
                raise CaptureError(f"live capture: no interface {self.interface!r}: {exc}") from exc
            raise CaptureError(
                f"live capture on {self.interface!r} with filter {self.bpf!r} failed: {type(exc).__name__}: {exc}"
            ) from exc
        from scapy.sendrecv import AsyncSniffer

        try:
            out = PcapNgFile(
                self.path,
                application="isight-conformance (live capture)",
                comment=f"case {self.case_id}: live capture on {self.interface} ({self.bpf})",
            )
        except OSError as exc:
            sock.close()
            raise CaptureError(f"live capture: cannot write {self.path}: {exc}") from exc
        out.add_interface(getattr(sock, "linktype", _LINKTYPE_ETHERNET), self.interface, f"filter: {self.bpf}")
        self._sock, self._out = sock, out
        started = threading.Event()
        sniffer = AsyncSniffer(opened_socket=sock, prn=self._write, store=False, started_callback=started.set)
        self._sniffer = sniffer
        sniffer.start()
        if not started.wait(10):  # the thread failed before sniffing
            self._sniffer = None
            self._close()
            raise CaptureError(f"live capture on {self.interface!r} did not start: {sniffer.exception}")
        return self

    def stop(self) -> int:
        """Stop sniffing, write what is still queued, close the file; packets written."""
        sniffer, self._sniffer = self._sniffer, None
        if sniffer is None:
            return self.packets
        try:
            if sniffer.running:
                sniffer.stop(join=True)
        except Exception as exc:  # noqa: BLE001 - the thread's own exception, re-raised by scapy
            self.error = exc
        self.error = self.error or sniffer.exception
        try:
            for _ in range(_DRAIN_LIMIT):  # bounded: a busy link may never leave the socket empty
                if not select.select([self._sock], [], [], 0)[0]:
                    break
                pkt = self._sock.recv()
                if pkt is not None:
                    self._write(pkt)
        except (OSError, ValueError) as exc:
            self.error = self.error or exc
        self._close()
        return self.packets

    def _close(self) -> None:
        with self._lock:
            if self._out is not None:
                self._out.close()
                self.error = self.error or self._out.error
            if self._sock is not None:
                try:
                    self._sock.close()
                except OSError:
                    pass
                self._sock = None

    def _write(self, pkt: Any) -> None:
        with self._lock:
            if self._out is None or self._out.closed:
                return
            comments = None
            if self._out.packets == 0 and self.case_id:
                comments = [f"{self.case_id}: live capture on {self.interface} ({self.bpf})"]
            self._out.write_packet(bytes(pkt), float(pkt.time), comments)

    def __enter__(self) -> LiveCapture:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
