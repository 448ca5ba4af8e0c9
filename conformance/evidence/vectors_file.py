"""Golden vector files (``isight-vectors-1``): load them, and map frames to their JSON form.

The vectors themselves live in ``vectors/frames/`` at the top of the repository and are
data derived by hand from PROTOCOL.md; this module only reads and writes the format
(the fuzzer writes shrunk failures in it, ``replay`` reads it).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..protocol import (
    DEFAULT_PROFILE,
    Action,
    Frame,
    PoseBlock,
    Profile,
    ToleranceBlock,
    TransferType,
    Transport,
    ValueBlock,
    peek_header,
)

SCHEMA = "isight-vectors-1"
DIRECTIONS = {"robot-to-box": TransferType.ROBOT_TO_BOX, "box-to-robot": TransferType.BOX_TO_ROBOT}
def _vectors_dir() -> Path:
    """``vectors/`` of a source checkout, else the copy a wheel ships as ``conformance/_vectors``."""
    package = Path(__file__).resolve().parents[1]  # conformance/
    checkout = package.parent / "vectors"
    return checkout if checkout.is_dir() else package / "_vectors"


#: The golden vectors and scripted sequences (data, not code).
REPO_VECTORS = _vectors_dir()


@dataclass(frozen=True)
class Vector:
    file: str
    tc_id: int
    comment: str
    clauses: tuple[str, ...]
    flags: tuple[str, ...]
    result: str  # valid | invalid | acceptable
    data: bytes
    frame: Mapping[str, Any] | None
    transport: Transport
    direction: TransferType
    profile: Profile

    @property
    def name(self) -> str:
        return f"{Path(self.file).stem}-tc{self.tc_id}"

    def other_first_index(self, profile: Profile) -> str | None:
        """Why these bytes cannot be judged under ``profile``: their blocks are indexed from their group's
        first index and ``profile`` reads another (B3); None when they can."""
        head = peek_header(self.data)
        if head is None or head.block_count == 0 or self.profile.first_index == profile.first_index:
            return None
        return (f"vector written for first index {self.profile.first_index} (its group's profile); "
                f"this run's profile uses --first-index {profile.first_index}")


def group_profile(group: Mapping[str, Any], base: Profile | None = None) -> Profile:
    """The receiver profile a test group asks for."""
    prof = group.get("profile", {})
    return (base or Profile()).replace(
        crc=group.get("crc", DEFAULT_PROFILE.crc),
        crc_byte_order=prof.get("crcByteOrder", DEFAULT_PROFILE.crc_byte_order),
        first_index=prof.get("firstIndex", 0),
    )


def load(path: str | Path) -> Iterator[Vector]:
    """Every vector of one file."""
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    if doc.get("schema") != SCHEMA:
        raise ValueError(f"{path}: not an {SCHEMA} file (schema={doc.get('schema')!r})")
    for group in doc["testGroups"]:
        profile = group_profile(group)
        for test in group["tests"]:
            yield Vector(
                file=str(path),
                tc_id=test["tcId"],
                comment=test.get("comment", ""),
                clauses=tuple(test.get("clauses", ())),
                flags=tuple(test.get("flags", ())),
                result=test["result"],
                data=bytes.fromhex(test["hex"]),
                frame=test.get("frame"),
                transport=Transport(group["transport"]),
                direction=DIRECTIONS[group["direction"]],
                profile=profile,
            )


def load_dir(directory: str | Path = REPO_VECTORS / "frames") -> list[Vector]:
    return [v for path in sorted(Path(directory).glob("*.json")) for v in load(path)]


def _float(value: float) -> float | str:
    if math.isnan(value):
        return "NaN"
    if math.isinf(value):
        return "Infinity" if value > 0 else "-Infinity"
    return value


def frame_to_dict(frame: Frame) -> dict[str, Any]:
    """A frame in the vector format (``check`` as read off the wire, big-endian)."""
    header = frame.header
    blocks: list[dict[str, Any]] = []
    for b in frame.blocks:
        if isinstance(b, PoseBlock):
            blocks.append({"index": b.index, "pose": [_float(v) for v in b.pose]})
        elif isinstance(b, ToleranceBlock):
            blocks.append({"index": b.index, "tolerance": _float(b.tolerance)})
        else:
            blocks.append({"index": b.index, "value": b.value})
    return {
        "startWord": header.start_word,
        "version": header.version,
        "transferType": int(header.transfer_type),
        "action": int(header.action),
        "blockType": int(header.block_type),
        "blockCount": header.block_count,
        "blockLength": header.block_length,
        "errorCode": header.error_code,
        "check": frame.check,
        "blocks": blocks,
    }


_SPECIAL = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def _unfloat(value: float | str) -> float:
    return float(_SPECIAL.get(value, value)) if isinstance(value, str) else float(value)


def _pose(values: list[float | str]) -> tuple[float, float, float, float, float, float]:
    x, y, z, w, p, r = (_unfloat(v) for v in values)
    return x, y, z, w, p, r


def frame_from_dict(data: Mapping[str, Any]) -> Frame:
    """The frame a vector's ``frame`` object describes (header counts follow from blocks)."""
    blocks: list[PoseBlock | ToleranceBlock | ValueBlock] = []
    for b in data.get("blocks", ()):
        if "pose" in b:
            blocks.append(PoseBlock(b["index"], _pose(b["pose"])))
        elif "tolerance" in b:
            blocks.append(ToleranceBlock(b["index"], _unfloat(b["tolerance"])))
        else:
            blocks.append(ValueBlock(b["index"], int(b["value"])))
    return Frame(
        TransferType(data["transferType"]), Action(data["action"]), tuple(blocks), data["errorCode"], data.get("check", 0)
    )


def write(path: str | Path, groups: list[dict[str, Any]], notes: Mapping[str, str] | None = None, description: str = "") -> None:
    """Write an ``isight-vectors-1`` file atomically."""
    count = sum(len(g["tests"]) for g in groups)
    doc: dict[str, Any] = {"schema": SCHEMA, "numberOfTests": count, "notes": dict(notes or {}), "testGroups": groups}
    if description:
        doc["description"] = description
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    tmp.replace(path)
