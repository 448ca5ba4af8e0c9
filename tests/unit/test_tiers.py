"""The tests sit in their tiers (tests/conftest.py): every test module in tests/unit, tests/integration or
tests/e2e, each test marked with its tier, and the unit tier free of sockets, threads and processes by
its imports (the fast loop, ``pytest tests/unit``, stays pure as modules are added)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parents[1]
TIERS = ("unit", "integration", "e2e")
#: what a unit test may not import: the means to open sockets, start threads or processes, or a loopback box
NOT_IN_UNIT = {"socket", "socketserver", "subprocess", "threading", "asyncio", "multiprocessing",
               "concurrent.futures", "tests.boxes", "tests.impls.boxcore"}


def _imports(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def test_every_test_module_sits_in_a_tier() -> None:
    loose = [p.relative_to(TESTS).as_posix() for p in TESTS.rglob("test_*.py")
             if p.relative_to(TESTS).parts[0] not in TIERS]
    assert not loose, f"test modules outside tests/unit, tests/integration and tests/e2e: {loose}"
    for tier in TIERS:
        assert (TESTS / tier / "__init__.py").is_file(), tier


def test_no_unit_module_imports_sockets_threads_or_processes() -> None:
    found = {p.name: sorted(_imports(p) & NOT_IN_UNIT) for p in sorted((TESTS / "unit").glob("*.py"))}
    bad = {name: mods for name, mods in found.items() if mods}
    assert not bad, f"unit tests importing sockets, threads or processes (move them to integration or e2e): {bad}"


def test_each_test_carries_its_tiers_marker(request: pytest.FixtureRequest) -> None:
    assert request.node.get_closest_marker("unit") is not None
    assert request.node.get_closest_marker("integration") is None and request.node.get_closest_marker("e2e") is None
