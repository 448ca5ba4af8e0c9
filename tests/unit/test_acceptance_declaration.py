"""The vendor's declaration: its TOML, the declared profile, and the declared / observed table."""

from __future__ import annotations

from pathlib import Path

import pytest

from conformance.acceptance.declaration import declared_profile, parse, read
from conformance.acceptance.declared_table import CONFIRMED, CONTRADICTED, INFERRED, NOT_EXERCISED, findings, table
from conformance.model.verdicts import CaseResult, Level, Verdict, WireLine
from conformance.protocol import DEFAULT_PROFILE
from conformance.report.summary import overall_line

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "declared.example.toml"


def _profile01(**discovered) -> CaseResult:
    return CaseResult("PROFILE-01", "Profile discovery", ("B3", "F7", "F4"), Level.MAY, Verdict.INFORMATIONAL,
                      pcap="pcaps/PROFILE-01.pcapng",
                      details={"discovered": discovered, "first_index": {"0": "answered error 0x0000", "1": "0x1001"}},
                      wire=[WireLine(0.0, 1, "→", "frame", "fe fe 00 01 23", "pose index 1"),
                            WireLine(1.0, 1, "←", "frame", "fe fe 00 01 10 23 10 01", "1001")])


def _case(case_id: str, verdict: Verdict, clauses: tuple[str, ...], **kw) -> CaseResult:
    return CaseResult(case_id, case_id, clauses, Level.MUST, verdict, **kw)


def test_the_example_in_docs_parses_and_names_every_choice() -> None:
    declaration = read(EXAMPLE)
    assert declaration.values["first_index"] == 0 and declaration.values["extension_e"] is True
    assert declaration.values["r6_framing"] in ("skip-announced", "resync-next-header", "close")
    assert set(declaration.profile_changes()) <= set(DEFAULT_PROFILE.to_dict())


@pytest.mark.parametrize("text, words", [
    ("first_index = 2", "must be one of 0, 1"),
    ("colour = 'red'", "unknown key 'colour'"),
    ("extension_e = 'yes'", "true or false"),
    ("crc = 'no-such-crc'", "unknown CRC-16"),
    ("connections = 0", "between 1 and"),
    ("first_index = ", "not TOML"),
    ("declared_by = 'x'", "declares nothing"),
])
def test_a_bad_declaration_is_one_line_naming_the_file(text: str, words: str) -> None:
    with pytest.raises(ValueError, match=words) as exc:
        parse(text, "--declared d.toml")
    assert str(exc.value).startswith("--declared d.toml") and "\n" not in str(exc.value)


def test_the_run_is_judged_under_the_declared_profile_and_a_contrary_flag_is_refused() -> None:
    declaration = parse('[declared]\nfirst_index = 1\nbyte_order = "little"\nr6_framing = "c"', "d")
    assert declaration.values["r6_framing"] == "close"
    profile = declared_profile(DEFAULT_PROFILE, declaration)
    assert (profile.first_index, profile.byte_order) == (1, "little")
    assert declared_profile(DEFAULT_PROFILE.replace(first_index=1), declaration).first_index == 1  # the same: fine
    with pytest.raises(ValueError, match="--declared d declares crc = 'modbus' but the command line asks for 'xmodem'"):
        declared_profile(DEFAULT_PROFILE.replace(crc="xmodem"), parse('crc = "modbus"', "d"))


def test_confirmed_contradicted_and_not_exercised_with_their_evidence() -> None:
    declaration = parse("first_index = 1\nbyte_order = 'big'\nconnections = 2\ncycle_state = 'per-box'\n"
                        "answer_latency_ms = 50\nextension_e = true", "d")
    cases = [_profile01(first_index=0, byte_order="big"),
             _case("S4-01", Verdict.PASS, ("S4", "T1"), latencies_ms=[3.0, 80.5], pcap="pcaps/S4-01.pcapng")]
    rows = {r["key"]: r for r in table(declaration, cases, {"extension": "not implemented (detected)"})}
    assert rows["first_index"]["status"] == CONTRADICTED and rows["first_index"]["observed"] == "0"
    assert rows["first_index"]["case"] == "PROFILE-01" and rows["first_index"]["pcap"] == "pcaps/PROFILE-01.pcapng"
    assert "fe fe 00 01 23" in rows["first_index"]["bytes"] and "answered error 0x0000" in rows["first_index"]["bytes"]
    assert rows["byte_order"]["status"] == CONFIRMED and rows["byte_order"]["case"] == "PROFILE-01"
    assert rows["connections"]["status"] == CONFIRMED and rows["connections"]["case"] == "S4-01"
    assert rows["cycle_state"]["status"] == NOT_EXERCISED
    assert rows["answer_latency_ms"]["status"] == CONTRADICTED and rows["answer_latency_ms"]["observed"] == "≤ 80.5 ms"
    assert rows["extension_e"]["status"] == CONTRADICTED
    found = {c.id: c for c in findings(list(rows.values()))}
    assert set(found) == {"DECL-first_index", "DECL-answer_latency_ms", "DECL-extension_e"}
    first = found["DECL-first_index"]
    assert first.verdict is Verdict.FAIL and first.judged == ("B3",) and first.pcap == "pcaps/PROFILE-01.pcapng"
    assert first.sent_hex == "fe fe 00 01 23" and first.received_hex == "fe fe 00 01 10 23 10 01"
    # the overall line can never say CONFORMS over a contradicted declaration
    assert overall_line([*cases, *found.values()]).startswith("DOES NOT CONFORM")


def test_a_declaration_the_box_bears_out_adds_no_finding() -> None:
    declaration = parse("first_index = 0\nconnections = 1", "d")
    cases = [_profile01(first_index=0), _case("S4-01", Verdict.FAIL, ("S4",))]
    rows = table(declaration, cases, {})
    assert [(r["key"], r["status"]) for r in rows] == [("first_index", CONFIRMED), ("connections", CONFIRMED)]
    assert findings(rows) == []


def test_without_a_declaration_the_table_is_inferred() -> None:
    rows = table(None, [_profile01(first_index=1, crc="xmodem", crc_byte_order="little")], {"extension": "detected"})
    assert {r["key"]: (r["observed"], r["status"]) for r in rows} == {
        "first_index": ("1", INFERRED), "crc": ("xmodem", INFERRED), "crc_byte_order": ("little", INFERRED),
        "extension_e": ("true", INFERRED)}
    assert all(r["declared"] is None for r in rows) and findings(rows) == []


def test_a_verdict_on_another_clause_of_the_case_tells_nothing_of_the_choice() -> None:
    """S4-01 failing on T1 (slow answers) says nothing of how many connections the box serves."""
    declaration = parse("connections = 2", "d")
    slow = _case("S4-01", Verdict.FAIL, ("S4", "T1"), judged=("T1",))
    assert [(r["key"], r["status"]) for r in table(declaration, [slow], {})] == [("connections", NOT_EXERCISED)]
    one = _case("S4-01", Verdict.FAIL, ("S4", "T1"), judged=("S4",))
    assert [(r["key"], r["status"]) for r in table(declaration, [one], {})] == [("connections", CONTRADICTED)]
