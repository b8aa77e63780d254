"""The dependency rule of docs/design.md, checked on every module's imports.

``stabilizer`` is a pure image library: it never imports the simulator (``sim``, mujoco,
dm_control) or rerun. ``sim.world`` is the simulated world: it never imports the evaluation
(``sim.harness``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RULES = {
    "stabilizer": ("sim", "mujoco", "dm_control", "rerun"),
    "sim/world": ("sim.harness",),
}


def imported_modules(path: Path) -> set[str]:
    """Absolute names of every module ``path`` imports (at any depth of its code)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
    return names


@pytest.mark.parametrize("package", sorted(RULES))
def test_no_module_imports_across_the_rule(package):
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"no modules under {package}"
    forbidden = RULES[package]
    offenders = {
        str(path.relative_to(ROOT)): sorted(
            name for name in imported_modules(path)
            if any(name == banned or name.startswith(banned + ".") for banned in forbidden))
        for path in files}
    assert {path: names for path, names in offenders.items() if names} == {}


def test_the_checker_sees_imports_inside_functions(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from sim.harness.runner import run\n    import mujoco\n")
    assert imported_modules(module) == {"sim.harness.runner", "mujoco"}
