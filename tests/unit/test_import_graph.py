"""The package's import graph has no circle, and its modules stay small rooms.

Every ``import`` in ``conformance/`` counts: at module level, under ``TYPE_CHECKING``, and
inside functions (a lazy import is still a dependency). Nodes are modules; a circle is any
strongly connected component with more than one module, or a module importing itself.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "conformance"
MAX_LINES = 450


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PACKAGE.rglob("*.py") if "_vectors" not in p.parts}


def _resolve(current: str, is_package: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = current.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - (node.level - 1)] if node.level > 1 else base
    return ".".join(base + ([node.module] if node.module else []))


def import_graph() -> dict[str, set[str]]:
    modules = _modules()
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        is_package = path.name == "__init__.py"
        for node in ast.walk(tree):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(name, is_package, node)
                targets = [f"{base}.{a.name}" for a in node.names] + [base]
            for target in targets:
                # the deepest module the import names (``from .x import y`` may name module x.y or a name in x)
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target and target != name and not name.startswith(target + "."):
                    graph[name].add(target)
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components with more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_walker_finds_a_planted_circle() -> None:
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_the_package_has_no_import_circle() -> None:
    graph = import_graph()
    assert "conformance.protocol.codec" in graph and graph["conformance.commands.run_flow"], "the walker found no imports"
    assert circles(graph) == []


def test_the_protocol_package_imports_nothing_of_the_suite() -> None:
    """Sans-I/O and at the bottom: conformance/protocol/ depends only on itself."""
    graph = import_graph()
    for name, deps in graph.items():
        if name.startswith("conformance.protocol"):
            assert {d for d in deps if d.startswith("conformance.")} <= {
                d for d in deps if d.startswith("conformance.protocol")}, name


def test_the_result_model_is_the_bottom_layer() -> None:
    """conformance/model/ (verdicts, signatures, root causes, exit statuses) sits at the bottom, beside
    protocol/: it may import only itself and conformance/protocol/, so every room above can use it."""
    graph = import_graph()
    assert graph["conformance.model.verdicts"], "the walker found no imports"
    for name, deps in graph.items():
        if name.startswith("conformance.model"):
            assert {d for d in deps if d.startswith("conformance.")
                    and not d.startswith(("conformance.model", "conformance.protocol"))} == set(), name


def test_fuzz_suite_and_cases_import_endpoints_only_to_start_the_bundled_box() -> None:
    graph = import_graph()
    for name, deps in graph.items():
        if name.startswith(("conformance.fuzz", "conformance.suite", "conformance.cases")):
            assert {d for d in deps if d.startswith("conformance.endpoints")} <= {"conformance.endpoints.bundled"}, name


def test_every_module_is_a_small_room() -> None:
    big = {name: n for name, path in _modules().items()
           if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert big == {}


def test_analyze_and_certify_are_siblings_on_the_observed_model() -> None:
    """Both judge observed traffic from conformance/observed/; analyze imports nothing of certify,
    and the shared model imports neither of them."""
    graph = import_graph()
    assert any(d.startswith("conformance.observed") for d in graph["conformance.analyze.sessions"]), "the walker lost analyze"
    for name, deps in graph.items():
        if name.startswith("conformance.analyze"):
            assert not {d for d in deps if d.startswith("conformance.certify")}, name
        if name.startswith("conformance.observed"):
            assert not {d for d in deps if d.startswith(("conformance.certify", "conformance.analyze"))}, name


def test_the_suite_imports_nothing_of_the_fuzzer() -> None:
    """The catalogue and the fuzzer share the exchange engine below them (conformance/harness/):
    no module of conformance/suite/ imports conformance/fuzz/, not even lazily."""
    graph = import_graph()
    assert graph["conformance.suite.case_context"], "the walker found no imports"
    leaks = {name: sorted(d for d in deps if d.startswith("conformance.fuzz"))
             for name, deps in graph.items() if name.startswith("conformance.suite")}
    assert {name: deps for name, deps in leaks.items() if deps} == {}


def test_the_harness_imports_only_the_protocol() -> None:
    """The exchange engine sits under the catalogue, the fuzzer and replay: it depends on nothing above it."""
    graph = import_graph()
    for name, deps in graph.items():
        if name.startswith("conformance.harness"):
            assert {d for d in deps if d.startswith("conformance.")
                    and not d.startswith(("conformance.harness", "conformance.protocol"))} == set(), name


def test_commands_are_the_top_layer_and_the_model_the_bottom() -> None:
    """conformance/commands/ (one module per subcommand) is imported by nothing of the package but
    ``__main__``; conformance/model/ (the result model, exit statuses) imports nothing above the protocol."""
    graph = import_graph()
    assert graph["conformance.commands"], "the walker lost the commands"
    for name, deps in graph.items():
        if not name.startswith("conformance.commands") and name != "conformance.__main__":
            assert not {d for d in deps if d.startswith("conformance.commands")}, name
        if name.startswith("conformance.model"):
            assert {d for d in deps if d.startswith("conformance.")
                    and not d.startswith(("conformance.model", "conformance.protocol"))} == set(), name


def test_the_package_root_holds_only_packages_and_its_entry_points() -> None:
    assert sorted(p.name for p in PACKAGE.glob("*.py")) == ["__init__.py", "__main__.py", "pytest_plugin.py",
                                                             "xdist_hooks.py"]
