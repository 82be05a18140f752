"""MuJoCo models of the arms, built in code from the kinematics' parameter objects.

    build_model(arm_name, scene="empty", *, arm_params=None, tool=None, **scene_kwargs)
    build_arm_model(arm, scene="empty", *, tool=None, **scene_kwargs)
    CollisionChecker(model, dof=arm.dof, resolution=0.01)

See ``docs/models.md``. The kinematics (``envs.kinematics``) never import mujoco; this
package, the env, the move pricer and the renderer do. ``MUJOCO_GL`` is chosen once, in
``envs/__init__.py``, which Python runs before any of them.
"""

from __future__ import annotations

from . import builders_dual, builders_industrial, builders_rod  # noqa: F401  (register builders)
from .builders import TREE_BUILDERS, ArmTree, register_tree_builder
from .collision import (
    DEFAULT_RESOLUTION,
    CollisionChecker,
    Contact,
    PathResult,
    body_lever_arms,
    candidate_pairs,
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
    "load_scene_file",
    "milling_cell_poses",
    "register_tree_builder",
]
