"""The certify-robot case catalogue: stable, valid IDs and clauses; every decoder clause has a case."""

from __future__ import annotations

from conformance.certify.records import INJECTIONS
from conformance.model.verdicts import Level
from conformance.observed.robot_catalogue import APPLIES, FRAME_SPECS, INJECT_SPECS, catalogue
from conformance.protocol import errors
from conformance.suite.record import _ID, CLAUSE_ID


def test_ids_and_clauses_are_valid_and_unique():
    for spec in catalogue() + catalogue(extension=True):
        assert _ID.match(spec.id), spec.id
        assert spec.clauses and all(CLAUSE_ID.match(c) for c in spec.clauses), spec.id
        assert spec.title and spec.requirement and spec.expect
    ids = [s.id for s in catalogue()]
    assert len(ids) == len(set(ids))


def test_the_ids_are_stable():
    assert [s.id for s in catalogue()] == [
        "RB-F1-01", "RB-F2-01", "RB-F3-01", "RB-F4-01", "RB-F5-01", "RB-F6-01", "RB-F7-01", "RB-A5-01",
        "RB-B1-01", "RB-B2-01", "RB-B3-01", "RB-B4-01", "RB-B5-01", "RB-E1-01", "RB-E2-01", "RB-E3-01",
        "RB-S1-01", "RB-A1-01", "RB-T2-01", "RB-T2-02", "RB-S5-01",
        "RB-INJECT-NOT-READY", "RB-INJECT-SLOW", "RB-INJECT-BUSY", "RB-INJECT-CLOSE-MID-CYCLE",
    ]
    assert "RB-E4-01" in {s.id for s in catalogue(extension=True)} and "RB-S1-01" not in {s.id for s in catalogue(True)}


def test_levels():
    levels = {s.id: s.level for s in catalogue()}
    assert levels["RB-B4-01"] is Level.SHOULD
    assert all(levels[s.id] is Level.MAY for s in INJECT_SPECS.values())
    assert all(level is Level.MUST for cid, level in levels.items() if cid not in ("RB-B4-01",)
               and not cid.startswith("RB-INJECT"))


def test_every_clause_a_request_can_break_has_a_frame_case():
    clauses = {cls.clause for cls in vars(errors).values() if isinstance(cls, type) and issubclass(cls, errors.ProtocolError)}
    # the codec's errors for a robot→box frame, plus the clauses a ShapeError names for requests
    reachable = (clauses - {"F", "A4"}) | {"B1", "B2", "E1", "E2", "E3", "F6"}
    assert reachable <= set(FRAME_SPECS), reachable - set(FRAME_SPECS)
    assert set(APPLIES) <= set(FRAME_SPECS)
    assert set(INJECT_SPECS) == set(INJECTIONS)


def test_frame_cases_take_the_clause_wording_from_the_registry():
    from conformance.protocol.clauses import clause

    for cid in ("F2", "F5", "F7", "B1", "B2", "B5", "E1"):
        spec = FRAME_SPECS[cid]
        assert spec.title == clause(cid).title
        assert spec.requirement == f"{cid}: {clause(cid).text}"
    # where the robot's side needs its own words, they stay (and still name the clause)
    assert FRAME_SPECS["F6"].requirement.startswith("F6 ") and "sender" in FRAME_SPECS["F6"].requirement
    assert all(s.requirement.startswith(s.clauses[0]) for s in FRAME_SPECS.values())
