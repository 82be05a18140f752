"""envs.kinematics is pure numpy: no simulator, RL, deep-learning or I/O imports."""

from __future__ import annotations

import ast
from pathlib import Path

import envs.kinematics

ALLOWED_MODULES = {"__future__", "numpy", "abc", "dataclasses", "functools", "typing", "math"}


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def test_kinematics_imports_only_numpy_and_the_standard_typing_modules():
    package = Path(envs.kinematics.__file__).parent
    files = sorted(package.glob("*.py"))
    assert len(files) >= 8
    for path in files:
        extra = imported_modules(path) - ALLOWED_MODULES
        assert not extra, f"{path.name} imports {sorted(extra)}"


def test_purity_check_catches_a_forbidden_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import mujoco\nfrom gymnasium import spaces\nimport torch.nn\n")
    assert imported_modules(bad) - ALLOWED_MODULES == {"mujoco", "gymnasium", "torch"}
