"""Issue 12: only the package benches/recording/ knows the HDF5 layout — no other module imports h5py or names a
dataset."""

from __future__ import annotations

import ast
import re

from tests import REPO_ROOT

PACKAGES = ("core", "analysis", "procedures", "drivers", "benches", "benchmarks", "scripts")
READER = REPO_ROOT / "benches" / "recording"
"""The recording package (its modules may import h5py and name datasets)."""
DATASET_PATH = re.compile(r"""["'](/?(imu|table)/(counter|time|accel|gyro|temperature|status|angles|rates))["']""")


def _python_files():
    for pkg in PACKAGES:
        root = REPO_ROOT / pkg
        if root.is_dir():  # benchmarks/out: git-ignored worktrees of old commits (benchmarks/bench_release.py)
            yield from sorted(p for p in root.rglob("*.py") if "out" not in p.relative_to(root).parts[:1])


def _imports_h5py(path) -> bool:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "h5py" for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "h5py":
            return True
    return False


def test_only_the_recording_module_imports_h5py():
    offenders = [str(p.relative_to(REPO_ROOT)) for p in _python_files() if READER not in p.parents and _imports_h5py(p)]
    assert offenders == [], f"modules outside benches/recording/ import h5py: {offenders}"
    assert _imports_h5py(READER / "reader.py") and _imports_h5py(READER / "writer.py")


def test_no_other_module_names_a_dataset_path():
    offenders = [
        f"{p.relative_to(REPO_ROOT)}: {m.group(1)}"
        for p in _python_files()
        if READER not in p.parents
        for m in DATASET_PATH.finditer(p.read_text(encoding="utf-8"))
    ]
    assert offenders == [], offenders
