"""MuJoCo models of the arms, built in code from the kinematics' parameter objects.

    build_model(arm_name, scene="empty", *, arm_params=None, tool=None, **scene_kwargs)
    build_arm_model(arm, scene="empty", *, tool=None, **scene_kwargs)
    CollisionChecker(model, dof=arm.dof, resolution=0.01)

See ``docs/models.md``. Only this package, the collision checker and the env import mujoco.
"""

from __future__ import annotations

import os

# Offscreen rendering needs a GL backend chosen before mujoco is first imported.
os.environ.setdefault("MUJOCO_GL", "egl")

from . import builders_dual, builders_industrial, builders_rod  # noqa: F401  (register builders)
from .builders import TREE_BUILDERS, ArmTree, register_tree_builder
from .collision import (
    DEFAULT_RESOLUTION,
    CollisionChecker,
    Contact,
    PathResult,
    body_lever_arms,
    candidate_pairs,
    lever_arms,
)
from .model import arm_spec, build_arm_model, build_model
from .scene_file import SceneFile, SceneFileError, load_scene_file
from .scenes import (
    RECOMMENDED_BRANCHES,
    SCENES,
    milling_cell_poses,
)

__all__ = [
    "DEFAULT_RESOLUTION",
    "RECOMMENDED_BRANCHES",
    "SCENES",
    "TREE_BUILDERS",
    "ArmTree",
    "CollisionChecker",
    "Contact",
    "PathResult",
    "SceneFile",
    "SceneFileError",
    "arm_spec",
    "body_lever_arms",
    "build_arm_model",
    "build_model",
    "candidate_pairs",
    "lever_arms",
    "load_scene_file",
    "milling_cell_poses",
    "register_tree_builder",
]
