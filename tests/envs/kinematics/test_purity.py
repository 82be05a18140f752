"""envs.kinematics is pure numpy: no simulator, RL, deep-learning or I/O imports.

The one exception is numba, the project's compiled-kernel tool, and its on-disk cache:
only ``compiled.py`` may import it (lazily, on the first IK call) and locate the cache
(``hashlib``, ``os``, ``pathlib``); importing the package and FK must not bring numba in.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import ikbranch_gym.envs.kinematics as kinematics

ALLOWED_MODULES = {
    "__future__", "numpy", "abc", "collections", "dataclasses", "functools", "itertools",
    "typing", "math",
}
#: Modules allowed beyond ALLOWED_MODULES, per file.
EXTRA_ALLOWED = {"compiled.py": {"numba", "hashlib", "os", "pathlib"}}


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
    package = Path(kinematics.__file__).parent
    files = sorted(package.glob("*.py"))
    assert len(files) >= 8
    for path in files:
        extra = imported_modules(path) - ALLOWED_MODULES - EXTRA_ALLOWED.get(path.name, set())
        assert not extra, f"{path.name} imports {sorted(extra)}"


def test_importing_the_package_does_not_import_numba_only_ik_does(tmp_path):
    code = (
        "import sys, numpy as np\n"
        "from ikbranch_gym.envs.kinematics import make_arm\n"
        "arm = make_arm('opw')\n"
        "pose = arm.fk(np.stack([arm.home] * 2))\n"
        "print('numba' in sys.modules)\n"
        "arm.ik(pose)\n"
        "print('numba' in sys.modules)\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            check=True, cwd=tmp_path)
    assert result.stdout.split() == ["False", "True"]


def test_purity_check_catches_a_forbidden_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("import mujoco\nfrom gymnasium import spaces\nimport torch.nn\n")
    assert imported_modules(bad) - ALLOWED_MODULES == {"mujoco", "gymnasium", "torch"}
