"""``--log FILE`` for the reference box: one JSON line per connection event and per frame in and out."""

from __future__ import annotations

import contextlib
import json
import time
from pathlib import Path
from typing import IO, Any

from ..protocol import Frame, ProtocolError
from .behaviour import Decision


class FrameLog:
    """``--log FILE``: one JSON object per line for every frame in and out.

    Keys: ``t`` (Unix time), ``conn`` (connection id, ``"udp"`` for datagrams),
    ``transport``, ``peer``, ``direction`` (``open``/``in``/``out``/``close``/``refused``), ``hex``,
    ``frame`` (decoded summary) or ``error`` (``clause``, ``message``, ``offset``),
    and ``decision``/``note`` for what the box did.
    """

    def __init__(self, target: str | Path | IO[str]) -> None:
        if isinstance(target, (str, Path)):
            self._fh: IO[str] = open(target, "a", encoding="utf-8", buffering=1 << 16)  # noqa: SIM115
            self._owned = True
        else:
            self._fh, self._owned = target, False
        self.records = 0

    def write(self, record: dict[str, Any]) -> None:
        record = {"t": round(time.time(), 6), **record}
        self._fh.write(json.dumps(record, ensure_ascii=False, separators=(",", ":")) + "\n")
        self.records += 1

    def frame(
        self, conn: int | str, transport: str, peer: str, raw: bytes, event: Frame | ProtocolError, decision: Decision
    ) -> None:
        record: dict[str, Any] = {"conn": conn, "transport": transport, "peer": peer, "direction": "in", "hex": raw.hex()}
        if isinstance(event, ProtocolError):
            record["error"] = {"clause": event.clause, "message": event.message, "offset": event.offset}
        else:
            record["frame"] = event.describe()
        record["decision"] = decision.reaction.value
        if decision.note:
            record["note"] = decision.note
        self.write(record)
        data = decision.tcp if transport == "tcp" else decision.udp
        if data is not None and decision.frame is not None:
            self.write({"conn": conn, "transport": transport, "peer": peer, "direction": "out", "hex": data.hex(),
                        "frame": decision.frame.describe()})

    def flush(self) -> None:
        with contextlib.suppress(ValueError, OSError):
            self._fh.flush()

    def close(self) -> None:
        self.flush()
        if self._owned:
            with contextlib.suppress(OSError):
                self._fh.close()
