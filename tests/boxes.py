"""Tiny deliberately-simple boxes for the project's own tests (loopback only, bounded).

``ScriptedBox(handler)`` listens on 127.0.0.1:0 and runs ``handler(conn_socket)`` on a
thread per connection; handlers below cover the behaviours a broken box can show.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
from collections.abc import Callable

from conformance.protocol import Frame, StreamDecoder, TransferType, answer, encode


class ScriptedBox:
    def __init__(self, handler: Callable[[socket.socket], None], accept: bool = True) -> None:
        self.handler = handler
        self.accept = accept
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(64)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._conns: list[socket.socket] = []

    @property
    def target(self) -> str:
        return f"127.0.0.1:{self.port}"

    def __enter__(self) -> ScriptedBox:
        thread = threading.Thread(target=self._serve, daemon=True)
        thread.start()
        self._threads.append(thread)
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        with contextlib.suppress(OSError):
            self.sock.close()
        for c in self._conns:
            with contextlib.suppress(OSError):
                c.close()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self._conns.append(conn)
            if not self.accept:
                continue  # accepted by the kernel, never served
            t = threading.Thread(target=self._run, args=(conn,), daemon=True)
            t.start()

    def _run(self, conn: socket.socket) -> None:
        with contextlib.suppress(OSError):
            self.handler(conn)


def answering(respond: Callable[[Frame], bytes | None] = lambda f: encode(answer(f.action))) -> Callable[[socket.socket], None]:
    """A handler answering each well-formed request with ``respond(frame)`` (None: silence);
    malformed input gets no answer."""

    def handler(conn: socket.socket) -> None:
        decoder = StreamDecoder(expect=TransferType.ROBOT_TO_BOX)
        conn.settimeout(10)
        while True:
            data = conn.recv(65536)
            if not data:
                return
            out = b""
            for event in decoder.feed(data):
                if isinstance(event, Frame):
                    out += respond(event) or b""
            if out:
                conn.sendall(out)

    return handler


def silent(conn: socket.socket) -> None:
    conn.settimeout(10)
    while conn.recv(65536):
        pass


def close_at_once(conn: socket.socket) -> None:
    conn.close()


def reset_at_once(conn: socket.socket) -> None:
    conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    conn.close()


def garbage(conn: socket.socket) -> None:
    conn.recv(65536)
    conn.sendall(b"hello, robot\r\n")
    silent(conn)
