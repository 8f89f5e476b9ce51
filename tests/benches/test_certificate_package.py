"""The certificate is one package with a one-way import graph (issue 12 item 9): no import loop."""

from __future__ import annotations

import ast

from tests import REPO_ROOT

PKG = REPO_ROOT / "benches" / "certificate"
ALLOWED = {  # module → package modules it may import (module-level or lazily)
    "content": {"budget"},
    "budget": set(),
    "drawing": set(),
    "plots": {"drawing"},
    "pdf": {"content"},
    "analyses": {"content"},
    "noise_report": {"analyses", "content", "plots"},
    "build": {"analyses", "content", "budget", "noise_report", "plots", "pdf"},
    "__init__": {"build", "content"},
}


def _package_imports(path) -> set[str]:
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if node.level == 1:
                out.add(mod.split(".")[0])
            elif mod.startswith("benches.certificate.") or mod == "benches.certificate":
                out.add(mod.removeprefix("benches.certificate").lstrip(".").split(".")[0] or "__init__")
    return out


def test_one_way_imports_inside_the_certificate_package():
    found = {p.stem: _package_imports(p) for p in PKG.glob("*.py")}
    assert set(found) == set(ALLOWED)
    for mod, deps in found.items():
        assert deps <= ALLOWED[mod], f"benches/certificate/{mod}.py imports {sorted(deps - ALLOWED[mod])}"


def test_no_module_outside_imports_the_old_certificate_modules():
    for p in (REPO_ROOT / "benches").rglob("*.py"):
        text = p.read_text(encoding="utf-8")
        for old in ("certificate_pdf", "certificate_plots", "uncertainty_budget"):
            assert f"benches.{old}" not in text and f".{old} import" not in text, (p, old)
