"""The observed cases (conformance/analyze/capture_catalogue.py): one per (clause, side)."""

from __future__ import annotations

import re

from conformance.analyze.capture_catalogue import SPECS, case_id, spec_for
from conformance.model.verdicts import Level
from conformance.observed.robot_catalogue import FRAME_SPECS
from conformance.protocol.clauses import clause as registry_clause
from conformance.report.summary import CLAUSES


def test_every_case_is_obs_clause_side_and_cites_known_clauses():
    for (clause, side), spec in SPECS.items():
        assert spec.id == case_id(clause, side) == f"OBS-{clause}-{side}"
        assert re.match(r"^OBS-[A-Z][0-9]-(box|robot)$", spec.id)
        assert spec.clauses[0] == clause and all(c in CLAUSES for c in spec.clauses)
        assert spec.title and spec.requirement and spec.expect


def test_both_sides_are_judged_and_the_robot_reads_certify_robots_catalogue():
    sides = {side for _clause, side in SPECS}
    assert sides == {"box", "robot"}
    for clause, spec in FRAME_SPECS.items():
        assert SPECS[(clause, "robot")].title == spec.title
    assert SPECS[("B4", "robot")].level is Level.SHOULD and SPECS[("R6", "box")].level is Level.SHOULD
    assert {c for c, s in SPECS if s == "box"} >= {"F1", "F3", "A1", "A2", "T1", "T2", "S5", "R1", "R7", "E2"}


def test_a_clause_without_a_spec_still_gets_a_case_from_the_registry():
    spec = spec_for("R3", "box")
    assert spec.id == "OBS-R3-box" and spec.level is Level.MUST
    assert spec.title.startswith(registry_clause("R3").title) and registry_clause("R3").text in spec.requirement
    assert spec_for("Z9", "robot").id == "OBS-Z9-robot"
