"""The clause registry (conformance/protocol/clauses.json) and its loader."""

from __future__ import annotations

import dataclasses
import json
import re
from importlib import resources
from pathlib import Path

import pytest

from conformance.protocol import clauses as registry
from conformance.protocol.clauses import (
    REGISTRY_VERSION,
    Clause,
    RegistryError,
    all_clauses,
    clause,
    clause_ids,
    families,
    parse_registry,
    text_of,
)
from conformance.runtime.profile_options import PROFILE_OPTIONS
from conformance.runtime.settings import SUITE_OPTIONS

EXPECTED_IDS = [f"{f}{i}" for f, n in zip("FBASTRE", (7, 5, 5, 6, 2, 7, 5)) for i in range(1, n + 1)]
RAW = resources.files("conformance.protocol").joinpath("clauses.json").read_text(encoding="utf-8")


def test_every_clause_once_in_document_order():
    assert list(all_clauses()) == EXPECTED_IDS
    assert clause_ids() == frozenset(EXPECTED_IDS)
    assert all(c.id == key for key, c in all_clauses().items())


def test_families_in_document_order():
    assert list(families()) == list("FBASTRE")
    assert families()["F"] == "Frame" and families()["E"].startswith("Extension")
    assert [c[0] for c in all_clauses()] == sorted((c[0] for c in all_clauses()), key=list(families()).index)


def test_version_is_the_files():
    assert REGISTRY_VERSION == json.loads(RAW)["version"] == "1"


def test_lookup_and_unknown_ids():
    assert clause("B3").title == "Block indexes start at 00 and rise by one"
    assert "FE FE" in text_of("F1")
    assert text_of("Z9") == "" and text_of("") == ""
    with pytest.raises(KeyError):
        clause("Z9")
    with pytest.raises(KeyError):
        clause("f1")  # ids are case-sensitive


def test_clauses_are_frozen_and_the_registry_cannot_be_changed_through_the_api():
    c = clause("F1")
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.title = "x"  # type: ignore[misc]
    got = all_clauses()
    del got["F1"]
    assert "F1" in all_clauses()
    assert isinstance(c.levels, tuple) and isinstance(c.flags, tuple)


def test_levels_the_suite_relies_on():
    levels = {c.id: c.levels for c in all_clauses().values()}
    # a MUST clause with a SHOULD part, and the reverse: the ones PROTOCOL.md states that way
    assert levels["F6"] == ("MUST", "SHOULD") and levels["A3"] == ("MUST", "SHOULD")
    assert levels["R7"] == ("MUST", "SHOULD") and levels["B4"] == ("MUST", "SHOULD")
    assert levels["A5"] == ("MUST", "MAY") and levels["S3"] == ("MUST", "MAY")
    assert levels["R6"] == ("SHOULD",)
    assert all(c.level == c.levels[0] for c in all_clauses().values())
    assert {c.level for c in all_clauses().values()} == {"MUST", "SHOULD"}


def test_every_flag_named_is_a_real_command_line_flag():
    real = {o.flag for o in PROFILE_OPTIONS} | {flag for flag, _ in SUITE_OPTIONS}
    named = {f for c in all_clauses().values() for f in c.flags}
    assert named <= real, sorted(named - real)
    # every profile option is some clause's business (the profile is PROTOCOL.md's decisions)
    assert {o.flag for o in PROFILE_OPTIONS} <= named, sorted({o.flag for o in PROFILE_OPTIONS} - named)


def test_every_option_help_names_a_clause_that_lists_it():
    for opt in PROFILE_OPTIONS:
        cited = re.findall(r"\b([FBASTRE][1-7])\b", opt.help)
        for cid in cited:
            assert opt.flag in clause(cid).flags, f"{opt.flag} cites {cid} but {cid} does not list it"


def test_decisions_say_so_and_quotes_carry_a_translation():
    for c in all_clauses().values():
        if "[decision]" in c.text:  # the source note says which part the source is silent on
            assert "[decision]" in c.source or c.source.startswith("Not in the source"), c.id
        if re.search(r"[\u4e00-\u9fff]", c.source):  # a Chinese quote comes with its English
            assert "—" in c.source, c.id
    assert all(clause(f"E{i}").source.startswith("Not in the source") for i in range(1, 6))


def _mutate(change) -> str:
    data = json.loads(RAW)
    change(data)
    return json.dumps(data)


@pytest.mark.parametrize(("change", "message"), [
    (lambda d: d["clauses"].append(dict(d["clauses"][0])), "appears twice"),
    (lambda d: d["clauses"].reverse(), "document order"),
    (lambda d: d["clauses"][0].update(level="SHOULD"), "strongest"),
    (lambda d: d["clauses"][0].update(levels=["SHOULD", "MUST"]), "strongest first"),
    (lambda d: d["clauses"][0].update(levels=["OPTIONAL"]), "levels must be"),
    (lambda d: d["clauses"][0].update(flags=["crc"]), "flags"),
    (lambda d: d["clauses"][0].pop("source"), "keys"),
    (lambda d: d["clauses"][0].update(id="X1"), "family letter"),
    (lambda d: d["clauses"][0].update(title=""), "must not be empty"),
    (lambda d: d.pop("version"), "version"),
    (lambda d: d["families"].pop("E"), "family letter"),
    (lambda d: d["families"].update(X="Extra"), "every family"),
    (lambda d: d["families"].update(F=""), "heading"),
])
def test_a_malformed_registry_is_refused_with_a_reason(change, message):
    with pytest.raises(RegistryError, match=message):
        parse_registry(_mutate(change))


def test_not_json_is_refused():
    with pytest.raises(RegistryError, match="not JSON"):
        parse_registry("{")


def test_the_shipped_file_parses_to_the_same_clauses():
    parsed = parse_registry(RAW)
    assert parsed.version == REGISTRY_VERSION and parsed.clauses == all_clauses()
    assert all(isinstance(c, Clause) for c in parsed.clauses.values())
    assert registry._load() is registry._load()  # read once


# -- docs/PROTOCOL.md says the same -------------------------------------------------------------
DOC = Path(__file__).resolve().parents[2] / "docs" / "PROTOCOL.md"
_HEADING = re.compile(r"^#### ([A-Z][0-9]+) · ([A-Z, ]+) · (.+)$")
_FAMILY = re.compile(r"^### ([A-Z]) — (.+)$")


def _doc_sections() -> dict[str, tuple[str, str, str]]:
    """clause id -> (levels as written, title, the section's text up to the next heading)."""
    out: dict[str, tuple[str, str, str]] = {}
    current: list[str] | None = None
    for line in DOC.read_text(encoding="utf-8").splitlines():
        m = _HEADING.match(line)
        if m:
            assert m.group(1) not in out, f"{m.group(1)} twice in PROTOCOL.md"
            current = []
            out[m.group(1)] = (m.group(2), m.group(3), "")
            body = current
            key = m.group(1)
        elif line.startswith("#"):
            current = None
        elif current is not None:
            body.append(line)
            out[key] = (*out[key][:2], "\n".join(body))
    return out


def test_protocol_doc_has_every_clause_with_the_registrys_level_and_title():
    sections = _doc_sections()
    assert list(sections) == list(all_clauses()), "PROTOCOL.md's clause headings are not the registry's, in order"
    for cid, (levels, title, _) in sections.items():
        c = clause(cid)
        assert levels == ", ".join(c.levels), f"{cid}: PROTOCOL.md says {levels}, the registry {c.levels}"
        assert title == c.title, f"{cid}: PROTOCOL.md titles it {title!r}, the registry {c.title!r}"


def test_protocol_doc_family_headings_are_the_registrys():
    found = [m.groups() for line in DOC.read_text(encoding="utf-8").splitlines() if (m := _FAMILY.match(line))]
    assert found == list(families().items())


def test_protocol_doc_names_the_registrys_flags_and_decisions():
    for cid, (_, _, body) in _doc_sections().items():
        lines = [line for line in body.splitlines() if line.startswith("Flags: ")]
        assert len(lines) == 1, f"{cid}: one 'Flags:' line expected"
        flags = tuple(re.findall(r"`(--[a-z-]+)`", lines[0]))
        assert flags == clause(cid).flags, f"{cid}: PROTOCOL.md lists {flags}, the registry {clause(cid).flags}"
        assert (lines[0] == "Flags: none.") == (not flags)
        assert ("**[decision]**" in body) == ("[decision]" in clause(cid).text), f"{cid}: [decision] differs"


def test_protocol_doc_quotes_come_with_a_translation():
    lines = DOC.read_text(encoding="utf-8").splitlines()
    quotes = [i for i, line in enumerate(lines) if line.startswith("> 原文：")]
    assert len(quotes) >= 25
    for i in quotes:
        assert lines[i + 1] == ">" and lines[i + 2].startswith("> Translation: "), f"line {i + 1}: no translation"
    for cid, (_, _, body) in _doc_sections().items():  # a clause whose registry entry quotes the source quotes it too
        if re.search(r"[\u4e00-\u9fff]", clause(cid).source) and cid != "S1":
            assert "> 原文：" in body, f"{cid}: the registry quotes the source, PROTOCOL.md does not"


def test_one_level_vocabulary_for_the_registry_the_verdicts_and_the_findings() -> None:
    from conformance.model import verdicts
    from conformance.protocol.answers import Expectation, Rule, Seen, judge_answer
    from conformance.protocol.clauses import LEVELS, all_clauses
    from conformance.protocol.levels import Level

    assert verdicts.Level is Level and LEVELS == (Level.MUST, Level.SHOULD, Level.MAY)
    assert all(isinstance(c.level, Level) and all(isinstance(lv, Level) for lv in c.levels) for c in all_clauses().values())
    finding, = judge_answer(Expectation(Rule.REJECT, "B3", 0x23, "a wrong index"), Seen(0x23, 0))
    assert finding.level is Level.MUST and verdicts.broken_verdict(finding.level) is verdicts.Verdict.FAIL
    assert f"{Level.SHOULD}" == "SHOULD" and "/".join(Level) == "MUST/SHOULD/MAY"
