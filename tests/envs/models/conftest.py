"""Shared parametrisations: every arm in ``ARM_NAMES`` has a MuJoCo tree (none skipped)."""

from __future__ import annotations

from ikbranch_gym.envs.kinematics import ARM_NAMES, make_arm
from ikbranch_gym.envs.models import SCENES

#: The two-arm systems: sites ``link3`` and ``link4`` instead of ``ee``.
TWO_ARM_NAMES = tuple(name for name in ARM_NAMES if make_arm(name).relative)
SINGLE_ARM_NAMES = tuple(name for name in ARM_NAMES if name not in TWO_ARM_NAMES)


#: The cells laid out for one arm: only that arm is tried in them.
CELL_ARMS = {"milling_cell": "anthropomorphic", "deburring_cell": "kuka_kr6_r700"}


def scene_cases() -> list[tuple[str, str]]:
    # "file" needs a scene_file: tests/envs/models/test_scene_file.py covers it.
    return [
        (arm, scene)
        for arm in ARM_NAMES
        for scene in SCENES
        if scene != "file" and CELL_ARMS.get(scene, arm) == arm
    ]
