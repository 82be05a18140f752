"""ikbranch-gym: Gymnasium environments for choosing closed-form IK branches.

``import ikbranch_gym`` (or this subpackage) registers every id in ``ENV_IDS``; then
``gym.make(id)`` needs nothing else. ``gym.make("ikbranch_gym:" + id)`` imports it itself.
"""

from __future__ import annotations

import copy
import math
import os

# The one place MUJOCO_GL is chosen: mujoco picks its GL backend when first imported, and
# every module that imports it (envs.models, envs.render, the env) is inside this package,
# so Python runs this first. Headless rendering (envs.render) needs EGL or OSMesa.
os.environ.setdefault("MUJOCO_GL", "egl")

import gymnasium as gym

#: id -> the constructor arguments that make it (see ``envs.ik_branch_env.IKBranchEnv``).
ENV_SPECS: dict[str, dict] = {
    "IKBranch/Cartesian-v1": {"arm": "cartesian", "scene": "random_clutter", "task": "random"},
    "IKBranch/Cylindrical-v1": {"arm": "cylindrical", "scene": "random_clutter", "task": "random"},
    "IKBranch/Spherical-v1": {"arm": "spherical", "scene": "random_clutter", "task": "random"},
    "IKBranch/Anthropomorphic-v1": {
        "arm": "anthropomorphic", "scene": "random_clutter", "task": "random",
    },
    "IKBranch/Cylindrical4-v1": {
        "arm": "cylindrical4", "scene": "random_clutter", "task": "random",
    },
    "IKBranch/ToolTransfer-v0": {
        "arm": "anthropomorphic", "scene": "milling_cell", "task": "tool_changes",
    },
    "IKBranch/DualRRPRPP-v0": {"arm": "dual_rrp_rpp", "scene": "empty", "task": "relative_motion"},
    "IKBranch/DualRRRPPP-v0": {"arm": "dual_rrr_ppp", "scene": "empty", "task": "relative_motion"},
    "IKBranch/DualPPRPRR-v0": {"arm": "dual_ppr_prr", "scene": "empty", "task": "relative_motion"},
    "IKBranch/RodMechanism-v1": {"arm": "rod_mechanism", "scene": "empty", "task": "random"},
}
# The ids above observe the ladder layout their published models were trained on.
for _kwargs in ENV_SPECS.values():
    _kwargs.setdefault("observation", "ladder")

#: The generation before (the version history in ``IKBranchEnv``'s docstring): compact
#: observations, and random clutter drawn anew at every episode.
_CLUTTER = {"scene": "random_clutter", "scene_seed": None, "task": "random",
            "observation": "compact"}
_COMPACT = {"observation": "compact"}
ENV_SPECS.update({
    "IKBranch/Cartesian-v2": {"arm": "cartesian", **_CLUTTER},
    "IKBranch/Cylindrical-v2": {"arm": "cylindrical", **_CLUTTER},
    "IKBranch/Spherical-v2": {"arm": "spherical", **_CLUTTER},
    "IKBranch/Anthropomorphic-v2": {"arm": "anthropomorphic", **_CLUTTER},
    "IKBranch/Cylindrical4-v2": {"arm": "cylindrical4", **_CLUTTER},
    "IKBranch/ToolTransfer-v1": {
        "arm": "anthropomorphic", "scene": "milling_cell", "task": "tool_changes", **_COMPACT,
    },
    "IKBranch/DualRRPRPP-v1": {
        "arm": "dual_rrp_rpp", "scene": "empty", "task": "relative_motion_free", **_COMPACT,
    },
    "IKBranch/DualRRRPPP-v1": {
        "arm": "dual_rrr_ppp", "scene": "empty", "task": "relative_motion_free", **_COMPACT,
    },
    "IKBranch/DualPPRPRR-v1": {
        "arm": "dual_ppr_prr", "scene": "empty", "task": "relative_motion_free", **_COMPACT,
    },
    "IKBranch/RodMechanism-v2": {
        "arm": "rod_mechanism", "scene": "empty", "task": "random", **_COMPACT,
    },
    # Industrial arms: their real limits, every turn branch.
    "IKBranch/KukaKR6-v0": {"arm": "kuka_kr6_r700", **_CLUTTER},
    "IKBranch/UR5e-v0": {"arm": "ur5e", **_CLUTTER},
    # The milling cell's tool changes with a real arm: an IRB 4600 (j4, j6 ±400°: 72
    # branches) placed between rack and mill, holding the tool in a gripper (0.17 m from
    # the flange to the grip, the tool across it, as the worked example's arm holds it).
    "IKBranch/IRB4600ToolTransfer-v0": {
        "arm": "abb_irb4600", "scene": "milling_cell", "task": "tool_changes", **_COMPACT,
        "scene_options": {"base_pos": [-1.0, 0.3, 0.0]},
        "tool": {"parts": [{"shape": "box", "size": [0.1, 0.1, 0.15]},
                           {"shape": "cylinder", "size": [0.025, 0.35],
                            "offset": {"pos": [0.0, 0.0, 0.17],
                                       "rpy": [-1.5707963267948966, 0.0, 0.0]}}],
                 "tcp": {"pos": [0.0, 0.0, 0.17]}},
    },
    # Unwinding: a nut runner whose last joint (±400°) must be turned the right way.
    "IKBranch/IRB2600Screwing-v0": {
        "arm": "abb_irb2600", "scene": "empty", "task": "screwing", **_COMPACT,
    },
})
# The ids above collide a cylinder as the capsule inside it and exclude the overlapping
# parts of wrists and guides from each other, as their published models were trained.
for _kwargs in ENV_SPECS.values():
    _kwargs.setdefault("collision_shapes", "inscribed")

#: The current generation (the version history in ``IKBranchEnv``'s docstring): each id of
#: the generation before, now collided as drawn (``collision_shapes="drawn"``).
SUCCESSORS: dict[str, str] = {
    "IKBranch/Cartesian-v2": "IKBranch/Cartesian-v3",
    "IKBranch/Cylindrical-v2": "IKBranch/Cylindrical-v3",
    "IKBranch/Spherical-v2": "IKBranch/Spherical-v3",
    "IKBranch/Anthropomorphic-v2": "IKBranch/Anthropomorphic-v3",
    "IKBranch/Cylindrical4-v2": "IKBranch/Cylindrical4-v3",
    "IKBranch/ToolTransfer-v1": "IKBranch/ToolTransfer-v2",
    "IKBranch/DualRRPRPP-v1": "IKBranch/DualRRPRPP-v2",
    "IKBranch/DualRRRPPP-v1": "IKBranch/DualRRRPPP-v2",
    "IKBranch/DualPPRPRR-v1": "IKBranch/DualPPRPRR-v2",
    "IKBranch/RodMechanism-v2": "IKBranch/RodMechanism-v3",
    "IKBranch/KukaKR6-v0": "IKBranch/KukaKR6-v1",
    "IKBranch/UR5e-v0": "IKBranch/UR5e-v1",
    "IKBranch/IRB4600ToolTransfer-v0": "IKBranch/IRB4600ToolTransfer-v1",
    "IKBranch/IRB2600Screwing-v0": "IKBranch/IRB2600Screwing-v1",
}
ENV_SPECS.update({new: {**copy.deepcopy(ENV_SPECS[old]), "collision_shapes": "drawn"}
                  for old, new in SUCCESSORS.items()})
#: A process job on a real arm: a KR 6 R700 deburrs the rim of a part in its fixture
#: (``envs/tasks/deburring.py``), the burr free about its axis (±90°, every 45°: the
#: action is branch × spin, 32 × 5), the burr allowed to touch the part and nothing else.
#: Its resets never applied the pass's step limit (30°: one configuration along the
#: pass), so its spec names none: moves that reconfigure the arm mid-pass are actions
#: there, as its published models were trained. -v1 keeps the pass in one configuration.
ENV_SPECS["IKBranch/KukaKR6Deburring-v0"] = {
    "arm": "kuka_kr6_r700", "scene": "deburring_cell", "task": "deburring",
    "observation": "compact", "collision_shapes": "drawn",
    "tool": {"parts": [{"shape": "cylinder", "size": [0.025, 0.13]},
                       {"shape": "cylinder", "size": [0.004, 0.04],
                        "offset": {"pos": [0.0, 0.0, 0.13]}}],
             "tcp": {"pos": [0.0, 0.0, 0.17]}},
    "tool_axis": [1.5707963267948966, 0.7853981633974483],
    "allowed_contacts": [["tool_1", "part*"]],
}
#: The deburring job with process continuity: no joint steps more than 30° inside the
#: pass, so the arm keeps one configuration along it (a move that would reconfigure it is
#: outside the mask).
ENV_SPECS["IKBranch/KukaKR6Deburring-v1"] = {
    **copy.deepcopy(ENV_SPECS["IKBranch/KukaKR6Deburring-v0"]),
    "max_joint_step": 0.5235987755982988,
}
#: Ids that see further along checked paths: the id before, whose observation shows per
#: branch the least travel of this many onward moves along collision-free paths the env
#: has checked (``onward_moves``; a branch whose every way on is blocked within them reads
#: 1): a trap in a per-episode clutter may close two or three waypoints ahead, and on an
#: arm with hundreds of branches the cheapest next move is often not where the cheapest
#: way on starts (docs/training.md).
ONWARD_SUCCESSORS: dict[str, tuple[str, int]] = {
    "IKBranch/Anthropomorphic-v3": ("IKBranch/Anthropomorphic-v4", 3),
    "IKBranch/UR5e-v1": ("IKBranch/UR5e-v2", 2),
    "IKBranch/KukaKR6-v1": ("IKBranch/KukaKR6-v2", 2),
}
ENV_SPECS.update({new: {**copy.deepcopy(ENV_SPECS[old]), "onward_moves": moves}
                  for old, (new, moves) in ONWARD_SUCCESSORS.items()})
#: Ids that check only the moves that matter: the id before, whose observation checks the
#: moves into the next waypoint in order of least travel until this many are free
#: (``checked_moves``); the rest read as colliding, and a move taken among them is checked
#: then and priced as it is. Of an arm's hundreds of branches most are turns of a joint
#: that no good plan takes next, and checking every path there was most of a step's cost
#: (docs/training.md).
CHECKED_SUCCESSORS: dict[str, tuple[str, int]] = {
    "IKBranch/UR5e-v2": ("IKBranch/UR5e-v3", 8),
}
ENV_SPECS.update({new: {**copy.deepcopy(ENV_SPECS[old]), "checked_moves": moves}
                  for old, (new, moves) in CHECKED_SUCCESSORS.items()})
#: Ids whose random task draws its chain of configurations within one turn about each
#: joint's zero (``task_joint_range`` [−π, π]; the id before draws them anywhere in the
#: ±2π limits): the arm starts, and the chain that makes the waypoints runs, where a
#: cell's work is usually taught, and every turn branch stays an action. Chains of ±2π
#: paths collided so often that drawing one was half of a reset (docs/training.md).
ONE_TURN_SUCCESSORS: dict[str, str] = {
    "IKBranch/UR5e-v3": "IKBranch/UR5e-v4",
}
ENV_SPECS.update({new: {**copy.deepcopy(ENV_SPECS[old]),
                        "task_joint_range": [[-math.pi, math.pi]] * 6}
                  for old, new in ONE_TURN_SUCCESSORS.items()})
ENV_IDS: tuple[str, ...] = tuple(ENV_SPECS)


def _latest(env_id: str) -> str:
    """The newest generation of ``env_id`` among the ids that see further, check less or
    draw their tasks within one turn."""
    for successors in (ONWARD_SUCCESSORS, CHECKED_SUCCESSORS):
        env_id = successors.get(env_id, (env_id,))[0]
    return ONE_TURN_SUCCESSORS.get(env_id, env_id)


#: The ids of the current generation, in ``ENV_IDS`` order of their lines.
CURRENT_IDS: tuple[str, ...] = (*(_latest(env_id) for env_id in SUCCESSORS.values()),
                                "IKBranch/KukaKR6Deburring-v1")

for _env_id, _kwargs in ENV_SPECS.items():
    if _env_id not in gym.registry:
        # gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point"): the
        # natively batched vector env (envs.vector_env).
        gym.register(_env_id, entry_point="ikbranch_gym.envs.ik_branch_env:IKBranchEnv",
                     vector_entry_point="ikbranch_gym.envs.vector_env:IKBranchVectorEnv",
                     kwargs=_kwargs)



#: What :func:`warm_up` compiles side by side in two processes, a phase at a time: every
#: kernel of a phase calls only kernels of itself and of the phases before (numba compiles
#: a callee that is not yet on disk again, in the caller's process).
WARM_UP_PHASES = (("configurations", "paths"), ("chain", "stepping"))


def warm_up(processes: int = 1) -> None:
    """Compile (or load from numba's on-disk cache) every kernel an episode runs: the IK
    driver, the collision filter, the clutter, the random chain, the stepping stages and
    observation assembly, in single and vector envs. ``make`` runs it
    once before parallel processes (test workers) start, so they load instead of compiling
    the same kernels at once. With ``processes=2`` the phases of ``WARM_UP_PHASES`` come
    first, each in two processes at once, and this process then loads what they compiled
    (and compiles what no phase reached)."""
    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
    from ikbranch_gym.envs.kinematics import compiled as kinematics
    from ikbranch_gym.envs.models import filter as collision

    if processes not in (1, 2):
        raise ValueError(f"warm_up: processes must be 1 or 2, got {processes!r}")
    if processes == 2:
        for phase in WARM_UP_PHASES:
            _run_side_by_side(phase)
    kinematics.warm_up()
    collision.warm_up()
    # A per-episode clutter (the random chain) seen several moves ahead, a fixed cell, an
    # arm with hundreds of branches (factored travel summaries), and a vector env (a stack
    # of scenes).
    for env_id in ("IKBranch/Anthropomorphic-v4", "IKBranch/ToolTransfer-v2",
                   "IKBranch/UR5e-v4"):
        env = gym.make(env_id, n_waypoints=2)
        env.reset(seed=0)
        unwrapped = env.unwrapped
        # Every id of ENV_SPECS is registered (above) with IKBranchEnv as its entry point.
        assert isinstance(unwrapped, IKBranchEnv)
        env.step(int(unwrapped.action_masks().argmax()))
        env.close()
    vec = gym.make_vec("IKBranch/Cartesian-v3", num_envs=2,
                       vectorization_mode="vector_entry_point")
    _, info = vec.reset(seed=0)
    vec.step(info["action_mask"].argmax(axis=1))
    vec.close()


def _run_side_by_side(parts: tuple[str, ...]) -> None:
    import subprocess
    import sys

    code = "import sys; from ikbranch_gym.envs import _warm_up_part; _warm_up_part(sys.argv[1])"
    running = [subprocess.Popen([sys.executable, "-c", code, part]) for part in parts]
    failed = [part for part, process in zip(parts, running, strict=True) if process.wait()]
    if failed:
        raise RuntimeError(f"warm_up: compiling {', '.join(failed)} failed (output above)")


def _warm_up_part(part: str) -> None:
    """One part of ``WARM_UP_PHASES``: the filter's configuration or path kernels (with the
    IK driver), the random chain (then a turned arm's reset up to its survey and the DP
    oracle's pass), or the stepping stages on a fixed cell (no chain)."""
    import numpy as np

    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
    from ikbranch_gym.envs.kinematics import compiled as kinematics
    from ikbranch_gym.envs.models import filter as collision
    from ikbranch_gym.envs.random_chain import random_chain_configurations
    from ikbranch_gym.envs.resets import begin_episodes

    if part in ("configurations", "paths"):
        if part == "configurations":
            kinematics.warm_up()
        collision.warm_up(configurations=part == "configurations", paths=part == "paths")
    elif part == "chain":
        from ikbranch_gym.agents import dp

        env = gym.make("IKBranch/Anthropomorphic-v4").unwrapped
        assert isinstance(env, IKBranchEnv)
        random_chain_configurations(env._task_arm, np.random.default_rng(0), 2,
                                    env.compiled_filter, env.checker.lever,
                                    env.checker.resolution)
        # The chain compiles in a fraction of the stepping part's time: this process goes
        # on to what the stepping part does not compile and what calls none of its stages,
        # the reset of an arm with turn branches up to its survey (its factored travel
        # summaries) and the DP oracle's pass, instead of leaving them to the end, where
        # one process would compile them alone.
        turned = gym.make("IKBranch/UR5e-v4", n_waypoints=2).unwrapped
        assert isinstance(turned, IKBranchEnv)
        begin_episodes([turned], [0], turned.compiled_filter, np.zeros(1, dtype=np.int64))
        dp.warm_up()
    elif part == "stepping":
        fixed = gym.make("IKBranch/ToolTransfer-v2", n_waypoints=2)
        fixed.reset(seed=0)
        assert isinstance(fixed.unwrapped, IKBranchEnv)
        fixed.step(int(fixed.unwrapped.action_masks().argmax()))
    else:
        raise ValueError(f"warm_up: no part {part!r}")


__all__ = ["CHECKED_SUCCESSORS", "CURRENT_IDS", "ENV_IDS", "ENV_SPECS", "ONWARD_SUCCESSORS",
           "SUCCESSORS", "warm_up"]
