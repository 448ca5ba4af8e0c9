"""The legal-choice table (conformance/protocol/legal.py) and the knobs of the independent implementations
(tests/impls) are the same space: every alternative of a row is a knob value and every knob has its row."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from conformance.commands import build_parser
from conformance.protocol import legal
from tests.impls import policy, robots
from tests.impls.box import VARIANTS, variant
from tests.impls.robot import ROBOTS
from tests.impls.robot import variant as robot_variant

ROOT = Path(__file__).resolve().parents[2]
KNOBS = {"box": policy.KNOBS, "robot": robots.KNOBS}


@pytest.mark.parametrize("side", legal.SIDES)
def test_every_alternative_is_a_knob_value_and_every_knob_has_its_row(side: str) -> None:
    rows = [c for c in legal.by_side(side) if c.knob]
    for c in rows:
        assert c.knob in KNOBS[side], f"{c.id}: {side} knob {c.knob!r} does not exist in tests/impls"
        assert set(c.alternatives) == set(KNOBS[side][c.knob]), f"{c.id}: alternatives differ from the knob's values"
        assert c.alternatives[0] == KNOBS[side][c.knob][0], f"{c.id}: the first alternative is the knob's default"
    assert sorted(c.knob for c in rows) == sorted(KNOBS[side]), "a knob without a row, or two rows for one knob"


def test_a_row_without_a_knob_is_a_flag_decision_and_says_so() -> None:
    for c in legal.CHOICES:
        assert c.kind in legal.KINDS and c.side in legal.SIDES and c.tester in legal.TESTERS, c.id
        assert c.clauses and len(c.alternatives) >= 2, c.id
        if not c.knob:
            assert c.tester == "flag" and c.note == legal.NO_KNOB, c.id


def _options(command: str) -> set[str]:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return set(sub.choices[command]._option_string_actions)


def test_every_flag_a_row_names_is_an_option_of_the_tester() -> None:
    for c in legal.CHOICES:
        options = _options("run" if c.side == "box" else "certify-robot")
        assert set(c.flags) <= set(c.alternatives), c.id
        for flags in c.flags.values():
            named = {w for w in flags.split() if w.startswith("--")}
            assert named and named <= options, f"{c.id}: {named - options} is not an option"


def test_the_flags_a_random_box_or_robot_asks_for_are_the_table_s() -> None:
    table_flags = {w for c in legal.CHOICES for f in c.flags.values() for w in f.split() if w.startswith("--")}
    for seed in range(40):
        box_flags = {w for w in variant("random", seed).choices.suite_args() if w.startswith("--")}
        robot_flags = {w for w in robot_variant("random", seed).choices.suite_args() if w.startswith("--")}
        assert box_flags | robot_flags <= table_flags


def test_the_doc_is_the_rendered_table() -> None:
    doc = (ROOT / "docs" / "LEGAL-CHOICES.md").read_text()
    assert doc == legal.render_markdown(), "run: python -m conformance.protocol.legal > docs/LEGAL-CHOICES.md"
    # the table is read on every machine: it names no path of the one it was written on
    assert not re.search(r"(?<![\w.])/(?:work|home|Users|tmp|root)/", doc), "LEGAL-CHOICES.md names a local path"


def test_every_named_implementation_takes_only_legal_knob_values() -> None:
    for v in VARIANTS.values():
        assert all(value in policy.KNOBS[k] for k, value in v.choices.knobs().items()), v.name
    for r in ROBOTS.values():
        assert all(value in robots.KNOBS[k] for k, value in r.choices.knobs().items()) or not r.conforming, r.name


def test_random_combinations_are_reproducible_and_cover_every_value() -> None:
    assert variant("random", 5).choices == variant("random", 5).choices
    assert variant("random", 5).choices != variant("random", 6).choices
    seen: dict[str, set[str]] = {k: set() for k in policy.KNOBS}
    for seed in range(300):
        for k, value in policy.random_choices(seed).knobs().items():
            seen[k].add(value)
    assert {k: set(v) for k, v in policy.KNOBS.items()} == seen


def test_a_broken_box_on_a_random_base_keeps_its_defect_and_its_fixed_knobs() -> None:
    for seed in range(20):
        v = variant("no-resync", seed)
        assert v.choices.defect == "no-resync" and v.choices.framing_garbage == "scan" and v.choices.udp == "off"
        assert variant("one-at-a-time", seed).choices.stream_port == "same"
    assert variant("nan-zero", 3).choices.nan == "accept" and "--checking" not in variant("nan-zero", 3).choices.suite_args()
    assert {variant("swapped-error", s).choices.knobs()["framing_version"] for s in range(20)} != {"resume+1"}
