"""The import graph of the house: layers import only downward, no cycles, one module reads HDF5.

Layers (DEVELOPERS.md): ``core`` ← ``analysis`` ← ``procedures``, ``drivers`` ← ``benches``. Every import
counts, at module level or inside a function. ``procedures`` and ``drivers`` sit side by side and do not
import each other, with one justified exception: the compiler checks commands against the table's limits,
so ``procedures`` may import the seam :mod:`drivers.protocols` (``AxisLimits``, ``AXIS_NAMES``).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

from tests import REPO_ROOT

PACKAGES = ("core", "analysis", "procedures", "drivers", "benches")
LAYER = {"core": 0, "analysis": 1, "procedures": 2, "drivers": 2, "benches": 3}
ALLOWED_SIDEWAYS = {("procedures", "drivers.protocols")}
"""(importing package, imported module) pairs allowed between the two middle layers."""
HDF5_READER = "benches.recording"


def _modules() -> dict[str, Path]:
    out: dict[str, Path] = {}
    for pkg in PACKAGES:
        for path in sorted((REPO_ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(REPO_ROOT).with_suffix("")
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imports(name: str, path: Path) -> Iterator[tuple[str, int]]:
    """(imported module, line) for every import in the file, relative imports resolved."""
    is_pkg = path.name == "__init__.py"
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base if is_pkg else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            yield mod, node.lineno
            for alias in node.names:  # "from pkg import module"
                if f"{mod}.{alias.name}" in MODULES:
                    yield f"{mod}.{alias.name}", node.lineno


def _project_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for name, path in MODULES.items():
        for mod, _ in _imports(name, path):
            if mod in MODULES and mod != name:
                graph[name].add(mod)
    return graph


def test_the_graph_is_not_empty() -> None:
    graph = _project_graph()
    assert len(graph) > 50 and sum(len(v) for v in graph.values()) > 100
    assert "procedures.steps" in graph["benches.runner"]


def _cycles() -> list[list[str]]:
    graph = _project_graph()
    # Tarjan's strongly connected components
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []
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
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    # a package __init__ importing its own sub-modules is not a loop of concerns
    return [c for c in cycles if not all(m.startswith(min(c, key=len)) for m in c)]


def test_no_import_cycles() -> None:
    """Type-checking-only imports count too: a loop of concerns is a loop even when Python can load it."""
    cycles = _cycles()
    assert cycles == [], f"import cycles: {cycles}"


def test_imports_go_down_the_layers_only() -> None:
    bad: list[str] = []
    for name, path in MODULES.items():
        pkg = name.split(".")[0]
        for mod, line in _imports(name, path):
            top = mod.split(".")[0]
            if top not in LAYER or top == pkg:
                continue
            if LAYER[top] > LAYER[pkg]:
                bad.append(f"{path.relative_to(REPO_ROOT)}:{line}: {pkg} (layer {LAYER[pkg]}) imports {mod}")
            elif LAYER[top] == LAYER[pkg] and not any(
                pkg == a and (mod == b or mod.startswith(b + ".")) for a, b in ALLOWED_SIDEWAYS
            ):
                bad.append(f"{path.relative_to(REPO_ROOT)}:{line}: {pkg} imports its sibling layer {mod}")
    assert bad == [], "imports against the layering:\n" + "\n".join(bad)


def test_the_sideways_exception_is_still_needed() -> None:
    """If procedures stops importing drivers.protocols, drop the exception above (it must not go stale)."""
    used = {
        mod
        for name, path in MODULES.items()
        if name.startswith("procedures.")
        for mod, _ in _imports(name, path)
        if mod.startswith("drivers")
    }
    assert used == {"drivers.protocols"}


def test_only_the_recording_module_imports_h5py() -> None:
    users = sorted(
        f"{path.relative_to(REPO_ROOT)}:{line}"
        for name, path in MODULES.items()
        if name != HDF5_READER
        for mod, line in _imports(name, path)
        if mod.split(".")[0] == "h5py"
    )
    assert users == [], "h5py imported outside benches/recording.py: " + ", ".join(users)


def test_commands_import_neither_each_other_nor_the_cli() -> None:
    """A command is thin: shared helpers live in benches/ (e.g. benches.arguments), not in another command."""
    bad = [
        f"{path.relative_to(REPO_ROOT)}:{line}: imports {mod}"
        for name, path in MODULES.items()
        if name.startswith("benches.commands.")
        for mod, line in _imports(name, path)
        if mod == "benches.cli" or (mod.startswith("benches.commands.") and mod != name)
    ]
    assert bad == [], "\n".join(bad)
