"""The shape of analysis/periodic/: no import loop between its modules, no command-line option named in it,
no file written by it (plots return figures)."""

from __future__ import annotations

import ast
import re

from tests import REPO_ROOT

PACKAGE = REPO_ROOT / "analysis" / "periodic"


def _imports() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for path in PACKAGE.glob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        deps = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("analysis.periodic."):
                deps.add(node.module.rsplit(".", 1)[1])
            elif isinstance(node, ast.Import):
                deps |= {a.name.rsplit(".", 1)[1] for a in node.names if a.name.startswith("analysis.periodic.")}
        graph[path.stem] = deps
    return graph


def test_no_import_loop_inside_the_package() -> None:
    graph = _imports()
    assert "error" not in graph  # the 865-line module is gone
    assert graph["compensator"] == set()  # the compensator stands alone
    state: dict[str, int] = {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for dep in graph.get(node, ()):
            assert state.get(dep) != 1, " → ".join([*path, node, dep])
            if dep not in state:
                visit(dep, [*path, node])
        state[node] = 2

    for node in graph:
        if node not in state:
            visit(node, [])


def test_no_command_line_option_or_file_writing_in_the_analysis() -> None:
    for path in PACKAGE.glob("*.py"):
        text = path.read_text(encoding="utf-8")
        assert not re.search(r"--[a-z][a-z-]+", text), f"{path.name} names a command-line option"
        for call in ("savefig(", "write_text(", "open(", "write_json(", "np.save("):
            assert call not in text, f"{path.name} writes files ({call})"
