"""``isight-conformance clauses``: the registry on the command line."""

from __future__ import annotations

import json

import pytest

from conformance.commands import main
from conformance.commands.clauses import format_text, select
from conformance.protocol.clauses import REGISTRY_VERSION, all_clauses, clause


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["clauses", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_one_clause_as_text_has_level_title_text_flags_and_source(capsys):
    code, out, err = run(capsys, "F6")
    assert code == 0 and err == ""
    first, *rest = out.splitlines()
    assert first == "F6  MUST, SHOULD  TCP check field is 00 00"
    body = " ".join(line.strip() for line in rest)
    assert "sender MUST put 00 00 in the check field" in body
    assert "flags: --tcp-check" in body
    assert "source:" in body and "缺省值" in body
    assert all(len(line) <= 88 or "“" in line for line in out.splitlines())  # wrapped (quotes may run wide)


def test_no_argument_prints_every_clause_in_document_order(capsys):
    code, out, _ = run(capsys)
    heads = [line.split()[0] for line in out.splitlines() if line and not line.startswith(" ")]
    assert code == 0 and heads == list(all_clauses())


def test_brief_is_one_line_per_clause(capsys):
    code, out, _ = run(capsys, "--brief", "R")
    assert code == 0
    assert out.splitlines() == [f"R{i:<2} {'/'.join(clause(f'R{i}').levels):<11} {clause(f'R{i}').title}"
                                for i in range(1, 8)]


def test_json_round_trips_the_registry(capsys):
    code, out, _ = run(capsys, "--format", "json", "e2", "B4", "E2")
    doc = json.loads(out)
    assert code == 0 and doc["version"] == REGISTRY_VERSION
    assert [c["id"] for c in doc["clauses"]] == ["E2", "B4"]  # case-insensitive, each once, in the order asked
    b4 = doc["clauses"][1]
    assert b4["levels"] == ["MUST", "SHOULD"] and b4["flags"] == list(clause("B4").flags)
    assert b4["text"] == clause("B4").text and b4["source"] == clause("B4").source


def test_all_clauses_as_json(capsys):
    code, out, _ = run(capsys, "--format", "json")
    assert code == 0 and [c["id"] for c in json.loads(out)["clauses"]] == list(all_clauses())


@pytest.mark.parametrize("bad", ["Z9", "F8", "FF", "1"])
def test_unknown_id_is_one_line_and_exit_2(capsys, bad):
    code, out, err = run(capsys, "F1", bad)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "unknown clause" in err


def test_select_and_format_helpers():
    assert [c.id for c in select(["t", "T1"])] == ["T1", "T2"]
    with pytest.raises(KeyError):
        select(["A6"])
    assert format_text(select(["S2"]), brief=True).startswith("S2  MUST")


