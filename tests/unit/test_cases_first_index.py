"""conformance/cases/ builds blocks by position and the codec applies the profile's first index (B3):
only the B3 cases, which test the first index itself, read ``first_index``, and no case leans on the
default of the protocol's module-level block builders (first index 0: under ``--first-index 1`` a
forgotten argument would silently build 0-based blocks). PROFILE-01 names the index it tries (0, 1)."""

from __future__ import annotations

import ast
from pathlib import Path

CASES = Path(__file__).resolve().parents[2] / "conformance" / "cases"
BUILDERS = {"pose_blocks", "tolerance_blocks", "value_blocks"}


def _case_id(function: ast.FunctionDef) -> str | None:
    for decorator in function.decorator_list:
        if (isinstance(decorator, ast.Call) and isinstance(decorator.func, ast.Name) and decorator.func.id == "case"
                and decorator.args and isinstance(decorator.args[0], ast.Constant)):
            return str(decorator.args[0].value)
    return None


def _findings() -> tuple[list[str], list[str]]:
    reads, builders = [], []
    for path in sorted(CASES.glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        allowed: set[int] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and (_case_id(node) or "").startswith("B3-"):
                allowed |= {id(inner) for inner in ast.walk(node)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr == "first_index" and id(node) not in allowed:
                reads.append(f"{path.name}:{node.lineno}")
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in BUILDERS
                    and len(node.args) + len(node.keywords) < 2):
                builders.append(f"{path.name}:{node.lineno} {node.func.id}")
    return reads, builders


def test_only_the_b3_cases_read_the_first_index() -> None:
    reads, _ = _findings()
    assert reads == []


def test_no_case_builds_blocks_with_the_default_first_index() -> None:
    _, builders = _findings()
    assert builders == []


def test_the_codec_applies_the_first_index() -> None:
    from conformance.protocol import Profile, codec_for

    codec = codec_for(Profile(first_index=1))
    assert [b.index for b in codec.pose_blocks([(0.0,) * 6] * 3)] == [1, 2, 3]
    assert [b.index for b in codec.tolerance_blocks([0.5])] == [1] and codec.block_index(2) == 3
    assert [b.index for b in codec_for(Profile()).value_blocks([7, 8])] == [0, 1]
