"""Arms registered in the kinematics before their MuJoCo tree exists are skipped, visibly."""

from __future__ import annotations

import pytest

from envs.kinematics import ARM_NAMES
from envs.models import SCENES, TREE_BUILDERS


def require_tree(arm_name: str) -> None:
    if arm_name not in TREE_BUILDERS:
        pytest.skip(f"no MuJoCo tree builder for {arm_name!r} yet")


def scene_cases() -> list[tuple[str, str]]:
    return [
        (arm, scene)
        for arm in ARM_NAMES
        for scene in SCENES
        if scene != "milling_cell" or arm == "anthropomorphic"
    ]
