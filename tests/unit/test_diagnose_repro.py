"""rootcause-N.json: an isight-vectors-1 file the schema accepts, with each frame's legal answers; read back by replay."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema

from conformance.diagnose import repro
from conformance.diagnose.hypotheses import Expect
from conformance.evidence.vectors_file import REPO_VECTORS, load
from conformance.model.verdicts import RootCause
from conformance.protocol import Action, PoseBlock, Profile, codec_for, request

SCHEMA = json.loads((REPO_VECTORS / "isight-vectors-1.schema.json").read_text(encoding="utf-8"))


def cause_with_repro(profile: Profile) -> RootCause:
    codec = codec_for(profile)
    pose = codec.encode(request(Action.POSE, (PoseBlock(profile.first_index, (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)),)))
    wrong = codec.encode(request(Action.POSE, (PoseBlock(profile.first_index + 1, (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)),)))
    frames = ((wrong, Expect("invalid", 0x23)), (pose, Expect("valid", 0x23)))
    cause = RootCause("RC2", ("A1", "A3"), "After it answers a request with an error …", "ev", ["X"], kind="state-leak",
                      confirmed=True, diagnosis={"repro": repro.repro_entry("RC2", frames)})
    return cause


def test_the_repro_file_is_a_vector_file_with_legal_answers_per_frame(tmp_path: Path) -> None:
    profile = Profile().replace(first_index=1)
    [path] = repro.write_repros(tmp_path, [cause_with_repro(profile), RootCause("RC3", ("A1",), "no repro", "")], profile)
    assert path.name == "rootcause-2.json"
    doc = json.loads(path.read_text())
    jsonschema.validate(doc, SCHEMA)
    assert doc["rootCause"]["id"] == "RC2" and doc["testGroups"][0]["profile"] == {"firstIndex": 1}
    assert [t["result"] for t in doc["testGroups"][0]["tests"]] == ["invalid", "valid"]
    assert [v.result for v in load(path)] == ["invalid", "valid"]  # the ordinary vector reader takes it too
    assert repro.is_repro(path) and not repro.is_repro(REPO_VECTORS / "frames" / "udp.json")
    name, frames, one_write = repro.load(path)
    assert not one_write and name.startswith("RC2: ") and [e for _, e in frames] == [Expect("invalid", 0x23), Expect("valid", 0x23)]


def test_a_root_cause_without_a_repro_writes_nothing(tmp_path: Path) -> None:
    assert repro.write_repros(tmp_path, [RootCause("RC1", ("S4",), "one at a time", "")], Profile()) == []
    assert list(tmp_path.iterdir()) == []
