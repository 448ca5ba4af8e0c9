"""The ``isight-sequence-1`` loader: errors that name the file and the step, agreement with the JSON
schema, and the shipped sequences."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from conformance.suite.sequence_format import SHIPPED_DIR, SequenceError, load, shipped

SCHEMA = json.loads((SHIPPED_DIR / "isight-sequence-1.schema.json").read_text())
HEAD = {"format": "isight-sequence-1", "id": "SEQ-T-1", "title": "t", "clauses": ["S1"], "level": "MUST"}


def _write(tmp_path: Path, steps: Any, name: str = "seq.json", **head: Any) -> Path:
    path = tmp_path / name
    path.write_text(json.dumps({**HEAD, **head, "steps": steps}))
    return path


# -- loader ---------------------------------------------------------------------------------------------

BAD = [
    ([{"open": "command"}, {"request": "CycleOnn"}], "steps[1] (request): field 'request': unknown action 'CycleOnn'"),
    ([{"open": "command"}, {"repeat": 2}], "steps[1] (repeat): missing field 'steps'"),
    ([{"open": "command"}, {"reqest": "NONE"}], "steps[1]: no verb"),
    ([{"open": "command"}, {"request": "NONE", "raw": "00"}], "steps[1]: several verbs"),
    ([{"open": "command"}, {"request": "NONE", "expect": {"errors": [1001]}}], "4 hex digits"),
    ([{"open": "command"}, {"request": "NONE", "expct": "ok"}], "unknown field 'expct'"),
    ([{"request": "NONE"}], "steps[0] (request): connection 'command' is not opened"),
    ([{"open": "command"}, {"repeat": 3, "steps": [{"request": "Pose", "on": "strem"}]}],
     "steps[1] (repeat).steps[0] (request): connection 'strem' is not opened"),
    ([{"open": "c"}, {"raw": "fe f"}], "steps[1] (raw): field 'raw': not hex bytes"),
    ([{"open": "c"}, {"request": "NONE", "on": "c", "poses": [[1, 2, 3, 4, 5, 6]]}], "'poses' go with Pose"),
    ([{"open": "s"}, {"stream": "s", "rate": "fast"}], "field 'rate': expected a number in [0.1, 10000] or one of profile"),
    ([{"open": "s"}, {"stop": "s"}], "no stream runs on 's'"),
    ([], "steps: expected a non-empty list of steps"),
    ([{"open": "c"}, {"raw": "fe fe 00 01 01 23 01 01 00 19 00 00", "on": "c", "probe": True}], "incomplete frame"),
    ([{"open": "c"}, {"raw": "fe fe 01 00 01 23 01 01 19 00 00 00", "on": "c", "probe": True}], "incomplete frame"),
]


@pytest.mark.parametrize(("steps", "message"), BAD, ids=[m[:30] for _, m in BAD])
def test_loader_names_file_and_step(tmp_path: Path, steps: Any, message: str) -> None:
    path = _write(tmp_path, steps)
    with pytest.raises(SequenceError) as exc:
        load(path)
    assert str(path) in str(exc.value) and message in str(exc.value), str(exc.value)


@pytest.mark.parametrize(("head", "message"), [
    ({"id": "S1-01"}, "must look like 'SEQ-S1'"), ({"clauses": ["S9"]}, "unknown clause IDs ['S9']"),
    ({"level": "MAY"}, "field 'level'"), ({"format": "v2"}, "field 'format'"), ({"extra": 1}, "unknown field 'extra'"),
])
def test_loader_header_errors(tmp_path: Path, head: dict[str, Any], message: str) -> None:
    with pytest.raises(SequenceError, match="header") as exc:
        load(_write(tmp_path, [{"open": "command"}], **head))
    assert message in str(exc.value)


def test_loader_not_json(tmp_path: Path) -> None:
    path = tmp_path / "x.json"
    path.write_text("{")
    with pytest.raises(SequenceError, match="not JSON"):
        load(path)


def test_schema_agrees_with_loader(tmp_path: Path) -> None:
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    validator = jsonschema.Draft202012Validator(SCHEMA)
    for seq in shipped():
        validator.validate(json.loads(seq.path.read_text()))
    for steps, message in BAD:
        if any(m in message for m in ("is not opened", "go with", "no stream runs", "incomplete frame")):
            continue  # semantic checks only the loader makes
        assert not validator.is_valid({**HEAD, "steps": steps}), message


def test_shipped_sequences() -> None:
    ids = {s.id: s for s in shipped()}
    assert set(ids) == {"SEQ-S1", "SEQ-E4", "SEQ-T2", "SEQ-S4", "SEQ-S5", "SEQ-R3", "SEQ-R4", "SEQ-R5"}
    assert ids["SEQ-E4"].requires == ("extension",)
