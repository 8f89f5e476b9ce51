"""The import graph of the house: layers import only downward, no cycles, one module reads HDF5.

Layers (DEVELOPERS.md): ``core`` ← ``analysis`` ← ``procedures``, ``drivers`` ← ``benches``. Every import
counts, at module level or inside a function. ``procedures`` and ``drivers`` sit side by side and do not
import each other, with one justified exception: the compiler checks commands against the table's limits,
so ``procedures`` may import the seam :mod:`drivers.protocols` (``AxisLimits``, ``AXIS_NAMES``).
"""

from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

from tests import REPO_ROOT

PACKAGES = ("core", "analysis", "procedures", "drivers", "benches")
LAYER = {"core": 0, "analysis": 1, "procedures": 2, "drivers": 2, "benches": 3}
ALLOWED_SIDEWAYS = {("procedures", "drivers.protocols")}
"""(importing package, imported module) pairs allowed between the two middle layers."""
HDF5_READER = "benches.recording"
"""The package that reads and writes the HDF5 layout (its modules may import h5py)."""


def _modules() -> dict[str, Path]:
    out: dict[str, Path] = {}
    for pkg in PACKAGES:
        for path in sorted((REPO_ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(REPO_ROOT).with_suffix("")
            parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imports_of(name: str, path: Path, node: ast.Import | ast.ImportFrom) -> Iterator[tuple[str, int]]:
    """(imported module, line) of one import statement, relative imports resolved."""
    if isinstance(node, ast.Import):
        for alias in node.names:
            yield alias.name, node.lineno
        return
    if node.level:
        base = name.split(".")
        base = base if path.name == "__init__.py" else base[:-1]
        base = base[: len(base) - (node.level - 1)]
        mod = ".".join(base + ([node.module] if node.module else []))
    else:
        mod = node.module or ""
    yield mod, node.lineno
    for alias in node.names:  # "from pkg import module"
        if f"{mod}.{alias.name}" in MODULES:
            yield f"{mod}.{alias.name}", node.lineno


def _imports(name: str, path: Path) -> Iterator[tuple[str, int]]:
    """(imported module, line) for every import in the file, relative imports resolved."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield from _imports_of(name, path, node)


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
        if name != HDF5_READER and not name.startswith(HDF5_READER + ".")
        for mod, line in _imports(name, path)
        if mod.split(".")[0] == "h5py"
    )
    assert users == [], "h5py imported outside benches/recording/: " + ", ".join(users)


def test_commands_import_neither_each_other_nor_the_cli() -> None:
    """A command is thin: shared helpers live in benches/ (e.g. benches.cli.arguments), not in another command."""
    bad = [
        f"{path.relative_to(REPO_ROOT)}:{line}: imports {mod}"
        for name, path in MODULES.items()
        if name.startswith("benches.cli.commands.")
        for mod, line in _imports(name, path)
        if mod in ("benches.cli", "benches.cli.main") or (mod.startswith("benches.cli.commands.") and mod != name)
    ]
    assert bad == [], "\n".join(bad)


LAZY_COMMENT = re.compile(r"#\s*lazy: [^()]+ \(--help time\)")
"""The mark of a justified function-level import: ``# lazy: <heavy library> (--help time)``."""
HEAVY = (
    "scipy",
    "matplotlib",
    "fpdf",
    "filterpy",
    "statsmodels",
    "pyvisa",
    "pymodbus",
    "tqdm",
    "starlette",
    "uvicorn",
    "sqlalchemy",
    "alembic",
)
"""Third-party libraries that cost ≥ 15 ms each to import, kept off the ``tablebench --help`` path. Not h5py
(≈ 35 ms): the one HDF5 package, benches/recording/, uses it at import time and is imported at the top of the
session and of most commands; taking it off the path is that module's change (import h5py where files are
opened), not a lazy import in every command."""


def _function_level_imports(path: Path) -> Iterator[tuple[ast.Import | ast.ImportFrom, str]]:
    """(statement, its source lines) of every import inside a function."""
    lines = path.read_text(encoding="utf-8").splitlines()
    for fn in ast.walk(ast.parse("\n".join(lines), str(path))):
        if isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            for node in ast.walk(fn):
                if isinstance(node, ast.Import | ast.ImportFrom):
                    yield node, "\n".join(lines[node.lineno - 1 : node.end_lineno])


def _unmarked_lazy_imports() -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for path in sorted((REPO_ROOT / "benches").rglob("*.py")):
        rel = path.relative_to(REPO_ROOT).as_posix()
        bad = [f"{rel}:{node.lineno}" for node, text in _function_level_imports(path) if not LAZY_COMMENT.search(text)]
        if bad:
            out[rel] = bad
    return out


def test_function_level_imports_in_benches_are_marked_lazy() -> None:
    """Imports sit at the top of a module; the only exceptions keep a heavy library out of ``--help``."""
    bad = _unmarked_lazy_imports()
    assert bad == {}, "function-level imports without '# lazy: <heavy lib> (--help time)':\n" + "\n".join(
        line for lines in bad.values() for line in lines
    )


def _load_time_imports(name: str, path: Path) -> set[str]:
    """What importing the module runs: its module-level imports (functions and TYPE_CHECKING blocks aside)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    out: set[str] = set()

    def visit(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                visit(node.orelse)
                continue
            if isinstance(node, ast.Import | ast.ImportFrom):
                out.update(mod for mod, _ in _imports_of(name, path, node))
            for field in ("body", "orelse", "finalbody", "handlers"):
                visit([n for n in getattr(node, field, []) if isinstance(n, ast.stmt | ast.excepthandler)])

    visit(tree.body)
    return out


def _heavy_on_import(module: str) -> set[str]:
    """The heavy third-party libraries that importing ``module`` loads (through project modules, statically)."""
    if module not in MODULES:
        return {module.split(".")[0]} & set(HEAVY)
    seen: set[str] = set()
    heavy: set[str] = set()
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        parts = name.split(".")
        todo += [".".join(parts[:i]) for i in range(1, len(parts)) if ".".join(parts[:i]) in MODULES]  # packages
        for mod in _load_time_imports(name, MODULES[name]):
            if mod in MODULES:
                todo.append(mod)
            elif mod.split(".")[0] in HEAVY:
                heavy.add(mod.split(".")[0])
    return heavy


def _lazy_targets() -> set[str]:
    """The modules benches/ imports inside functions with a ``# lazy`` mark."""
    return {
        max((mod for mod, _ in _imports_of(name, path, node)), key=len)  # "from benches import factory": the module
        for name, path in MODULES.items()
        if name.startswith("benches.")
        for node, text in _function_level_imports(path)
        if LAZY_COMMENT.search(text)
    }


def test_the_help_path_loads_no_heavy_library() -> None:
    """``tablebench --help`` imports the CLI and every command module; none of them may load a heavy library."""
    commands = [m for m in MODULES if m.startswith("benches.cli.commands.")]
    heavy = {m: _heavy_on_import(m) for m in ["benches.cli", *commands]}
    assert {m: h for m, h in heavy.items() if h} == {}


def test_every_lazy_import_keeps_a_heavy_library_out_of_help() -> None:
    """A ``# lazy`` import must be worth it: what it imports loads a heavy library (else import it at the top)."""
    lazy = _lazy_targets()
    assert "benches.identify" in lazy  # the check below has something to check
    assert {m: sorted(_heavy_on_import(m)) for m in sorted(lazy) if not _heavy_on_import(m)} == {}


def test_no_test_skips() -> None:
    """A missing module, dependency or shipped file fails the suite instead of silently skipping its tests; the only
    skip is ``tests.not_run_here`` (a browser or database server missing here), which prints a visible line."""
    skip = re.compile(r"importorskip|pytest\.skip\(|mark\.skip")
    here = Path(__file__).resolve()
    bad = [
        f"{path.relative_to(REPO_ROOT)}:{i}"
        for path in sorted((REPO_ROOT / "tests").rglob("*.py"))
        if path.resolve() not in (here, (REPO_ROOT / "tests" / "__init__.py").resolve())  # not_run_here: visible
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if skip.search(line)
    ]
    assert bad == [], "tests that skip: " + ", ".join(bad)


MAX_FUNCTION_LINES = 120
MAX_MODULE_LINES = 1000
SIZE_ALLOWED: dict[str, str] = {}
"""Offenders still being split by the helper that owns them: path (or path:function) → who removes them."""


def test_no_function_over_120_lines_and_no_module_over_1000_lines() -> None:
    """Outside tests/ (as /work/tools/longfuncs.py counts: a module's newlines, a function's lines incl. decorators'
    first line to its last)."""
    bad = []
    for pkg in (*PACKAGES, "benchmarks", "scripts"):
        root = REPO_ROOT / pkg
        for path in sorted(root.rglob("*.py")) if root.is_dir() else []:
            rel = path.relative_to(REPO_ROOT).as_posix()
            if rel.startswith("benchmarks/out/"):  # generated (git-ignored): bench_release's worktrees of old commits
                continue
            src = path.read_text(encoding="utf-8")
            if src.count("\n") > MAX_MODULE_LINES and rel not in SIZE_ALLOWED:
                bad.append(f"{rel}: {src.count(chr(10))} lines")
            for node in ast.walk(ast.parse(src, rel)):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                    n = (node.end_lineno or node.lineno) - node.lineno + 1
                    if n > MAX_FUNCTION_LINES and f"{rel}:{node.name}" not in SIZE_ALLOWED:
                        bad.append(f"{rel}:{node.lineno} {node.name}: {n} lines")
    assert bad == [], "too long (split them):\n" + "\n".join(bad)


def test_the_size_allow_list_is_not_stale() -> None:
    """An entry whose offender is gone must be removed."""
    for entry in SIZE_ALLOWED:
        path, _, func = entry.partition(":")
        p = REPO_ROOT / path
        assert p.exists(), f"{entry}: gone; remove it from SIZE_ALLOWED"
        src = p.read_text(encoding="utf-8")
        if not func:
            assert src.count("\n") > MAX_MODULE_LINES, f"{entry}: now short enough; remove it from SIZE_ALLOWED"
        else:
            sizes = [(n.end_lineno or n.lineno) - n.lineno + 1 for n in ast.walk(ast.parse(src))
                     if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef) and n.name == func]  # fmt: skip
            assert sizes and max(sizes) > MAX_FUNCTION_LINES, f"{entry}: now short enough; remove it"


def test_no_file_of_the_project_points_outside_it_for_its_methods() -> None:
    """Methods and protocols are documented in docs/; nothing cites the session's spec folder outside the repo."""
    import subprocess

    needle = "shared" + "/spec"
    files = subprocess.run(["git", "ls-files"], cwd=REPO_ROOT, capture_output=True, text=True, check=True).stdout
    bad = []
    for rel in files.split():
        p = REPO_ROOT / rel
        try:
            text = p.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            continue
        bad += [f"{rel}:{i}" for i, line in enumerate(text.splitlines(), 1) if needle in line]
    assert bad == [], "cite docs/methods or docs/protocols instead:\n" + "\n".join(bad)


SPEC_NAMES = ("accelerometer-calibration", "gyro-calibration", "time-base", "thermal-chamber", "noise-variance",
              "periodic-error", "drift-timeseries", "simulation", "imu-frames", "acutrol-acl", "wire-protocols")


def test_every_documentation_reference_resolves_inside_the_project() -> None:
    """A ``docs/….md`` cited anywhere exists, and no file cites a method file by a bare name outside docs/."""
    import subprocess

    files = subprocess.run(["git", "ls-files"], cwd=REPO_ROOT, capture_output=True, text=True, check=True).stdout
    bare = re.compile(r"(?<![/A-Za-z0-9_-])(" + "|".join(SPEC_NAMES) + r")\.md")
    cited = re.compile(r"docs/[A-Za-z0-9_./-]+?\.md")
    missing, unresolved = [], []
    for rel in files.split():
        if not rel.endswith((".py", ".md", ".yaml")) or rel == "DEVELOPERS.md" or rel.startswith("docs/"):
            continue
        text = (REPO_ROOT / rel).read_text(encoding="utf-8")
        for i, line in enumerate(text.splitlines(), 1):
            missing += [f"{rel}:{i}: {m}" for m in cited.findall(line) if not (REPO_ROOT / m).is_file()]
            unresolved += [f"{rel}:{i}: {m.group(0)}" for m in bare.finditer(line)]
    assert missing == [] and unresolved == [], "\n".join(missing + unresolved)


def test_command_summaries_name_every_command_with_its_help() -> None:
    """``tablebench --help`` lists the commands from ``SUMMARIES`` without importing them: it must name every
    command module, with the one-line help the module itself registers."""
    from benches.cli import build_parser
    from benches.cli.commands import SUMMARIES

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    registered = {ca.dest: ca.help for ca in sub._choices_actions}
    assert SUMMARIES == registered, (
        "benches/cli/commands/__init__.py SUMMARIES must list every command with the help its module registers"
    )


def test_help_imports_no_command_and_no_numpy() -> None:
    """``tablebench --help`` imports no command module and nothing numerical (issue 32: ≤ 8× ``python -c pass``)."""
    code = (
        "import sys\nfrom benches.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'h5py', 'yaml', 'scipy') "
        "or m.startswith('benches.cli.commands.'))\nprint('IMPORTED:' + ','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO_ROOT, check=True)
    assert out.stdout.strip().splitlines()[-1] == "IMPORTED:"


DEVICE_REGISTRY = "benches/devices.py"
NAME_ALLOWED = {
    "drivers/chamber/bench_section.py": "the chamber's own 'modbus:' sub-section (its link framing), not a table",
}
"""Files that spell a registered name for another meaning (file → why)."""


def test_controller_names_are_resolved_in_one_module() -> None:
    """Every turntable-controller name a bench file can use (``turntable.driver``, ``simulation.controller``) is
    spelled as a string in the device registry only; everything else asks the registry."""
    from benches import devices

    names = {*devices.controller_names(), *devices.simulated_controller_names()}
    assert {"acutrol", "modbus", "modbus-tcp"} <= names  # the check below has something to check
    literal = re.compile("|".join(rf"[\"']{re.escape(n)}[\"']" for n in sorted(names)))
    offenders = []
    for path in MODULES.values():
        rel = path.relative_to(REPO_ROOT).as_posix()
        if rel == DEVICE_REGISTRY or rel in NAME_ALLOWED:
            continue
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if literal.search(line):
                offenders.append(f"{rel}:{i}: {line.strip()}")
    assert offenders == [], "controller names outside benches/devices.py:\n" + "\n".join(offenders)
    for rel in NAME_ALLOWED:  # the allow-list is not stale
        assert literal.search((REPO_ROOT / rel).read_text(encoding="utf-8")), rel
