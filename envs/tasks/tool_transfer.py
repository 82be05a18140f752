"""The milling cell's tasks: the paper's transfer, and sequences of tool changes."""

from __future__ import annotations

from functools import cache, lru_cache

import numpy as np

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.paper_example import example_poses, rack_slot_poses

from .base import FreePredicate, PathPredicate, Task, require_pose_arm, task_generator

#: A tool is symmetric about its axis y3, so the gripper may hold it either way round:
#: the second grip is the first turned half a turn about y3.
GRIPS = (np.eye(3), np.diag([-1.0, 1.0, -1.0]))
#: Approach and retreat (m, along +Z0): a tool leaves its cradle upwards, so every pick is
#: entered and left through the pose this far above the slot. (The spindle is reached
#: straight from there, as in the paper's transfer.)
RACK_CLEARANCE = 0.15


@cache
def _cell_poses() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slots and the poses above them (grips, S, 4, 4), the spindle (grips, 4, 4); computed
    once, read-only."""
    slots, spindle = rack_slot_poses(), example_poses()[1]
    slot_grips = np.repeat(slots[None], len(GRIPS), axis=0)
    spindle_grips = np.repeat(spindle[None], len(GRIPS), axis=0)
    for grip, turn in enumerate(GRIPS):
        slot_grips[grip, :, :3, :3] = slots[:, :3, :3] @ turn
        spindle_grips[grip, :3, :3] = spindle[:3, :3] @ turn
    above = slot_grips.copy()
    above[..., 2, 3] += RACK_CLEARANCE
    poses = (slot_grips, above, spindle_grips)
    for pose in poses:
        pose.flags.writeable = False
    return poses


@cache
def _tool_cycles() -> np.ndarray:
    """Each tool's four poses (grips, S, 4, 4, 4): above its slot, in it, above it again,
    in the spindle; read-only."""
    slots, above, spindle = _cell_poses()
    cycles = np.stack([above, slots, above, np.broadcast_to(spindle[:, None], above.shape)],
                      axis=2)
    cycles.flags.writeable = False
    return cycles


@cache
def _parked_configurations(arm: Arm) -> np.ndarray:
    """Home and every valid front-shoulder branch above a slot or in the spindle, either
    grip: where earlier jobs leave the arm."""
    _, above, spindle = _cell_poses()
    solutions, valid = arm.ik(np.concatenate([above.reshape(-1, 4, 4), spindle]))
    # Reaching over the base (the back-shoulder branches) parks the arm where no
    # collision-free way leads back to the front: a task from there could not be done.
    valid &= np.array([label.startswith("front") for label in arm.branch_labels])
    parked = np.concatenate([arm.home[None], solutions[valid]])
    parked.flags.writeable = False
    return parked


@cache
def _grip_candidates(arm: Arm) -> tuple[np.ndarray, np.ndarray]:
    """The IK of every pose of a tool change, per grip: (grips, 2 S + 1, K, dof) solutions
    and their validity (the slots, the poses above them, the spindle); computed once per
    arm, read-only."""
    slots, above, spindle = _cell_poses()
    poses = np.concatenate([slots, above, spindle[:, None]], axis=1)
    solutions, valid = arm.ik(poses)
    solutions.flags.writeable = valid.flags.writeable = False
    return solutions, valid


@lru_cache(maxsize=256)
def _usable_grips(arm: Arm, is_free: FreePredicate) -> np.ndarray:
    """The grips (indices into ``GRIPS``) with which every pose of a tool change has a
    collision-free branch: in each slot, above it, and in the spindle. The worked
    example's arm, a wrist centre with nothing around it, has both; a real wrist may not
    fit under the spindle holding the tool one way round. ``ValueError`` if none is."""
    solutions, valid = _grip_candidates(arm)
    free = np.zeros_like(valid)
    if valid.any():
        free[valid] = is_free(solutions[valid])
    usable = [grip for grip in range(len(GRIPS)) if free[grip].any(axis=-1).all()]
    # Remembered per (arm, predicate): an env's predicate answers for its one milling cell,
    # which never changes (this task needs that scene), so the answer holds for its life.
    if not usable:
        raise ValueError(f"{arm.name} cannot change tools in this cell: with either grip some "
                         "slot or the spindle has no collision-free branch (place its base "
                         "elsewhere: scene_options base_pos)")
    grips = np.array(usable)
    grips.flags.writeable = False
    return grips


@lru_cache(maxsize=256)
def _free_parked_configurations(arm: Arm, is_free: FreePredicate) -> np.ndarray:
    """The collision-free ones of ``_parked_configurations``, remembered per (arm,
    predicate) as ``_usable_grips`` is (the milling cell never changes); read-only."""
    parked = _parked_configurations(arm)
    free = parked[is_free(parked)]
    free.flags.writeable = False
    return free


def _require_anthropomorphic(arm: Arm, scene: str) -> None:
    if arm.name != "anthropomorphic":
        raise ValueError(f"the milling-cell tasks need the anthropomorphic arm, not {arm.name!r}")


def _require_cell(arm: Arm, scene: str) -> None:
    require_pose_arm(arm, scene)
    if scene != "milling_cell":
        raise ValueError("tool_changes needs scene='milling_cell' (its rack and spindle)")


@task_generator(default_waypoints=2, check_arm=_require_anthropomorphic, fixed_waypoints=True,
                finite_poses=True)
def paper_transfer(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """Klyuiko's worked example: the arm stands at position 1 with a free choice of its
    branch (the first step costs no motion), then transfers to position 2. The least
    total travel is the paper's 275.15°."""
    if n_waypoints != 2:
        raise ValueError("paper_transfer has exactly 2 waypoints (positions 1 and 2)")
    return Task(start=arm.home, poses=example_poses(), free_start=True)


@task_generator(default_waypoints=8, check_arm=_require_cell, finite_poses=True)
def tool_changes(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """Tool changes in the milling cell, four waypoints a tool: above a rack slot, in the
    slot (pick), above it again, in the spindle (insert); then the next tool
    (``n_waypoints`` may cut the cycle anywhere; the default is two tools).

    Randomised: the slot of each tool, its grip (either way round about its axis, kept
    from slot to spindle; of the grips with which every pose has a free branch) and the
    start, where an earlier job left the arm: home or a collision-free front-shoulder branch
    above a slot or in the spindle. The spindle pose is the paper's position 2; slot 0 is
    its position 1. The pose set is finite, so the env's path-collision cache covers every
    move after warm-up.
    """
    tools = -(-n_waypoints // 4)
    usable = _usable_grips(arm, is_free)
    cycles = _tool_cycles()
    # One scalar draw at a time is the stream of one draw of ``size=tools`` (NumPy fills
    # an array of bounded integers element by element), and a quarter of the time.
    grips = [usable[rng.integers(len(usable))] for _ in range(tools)]
    chosen = [rng.integers(cycles.shape[1]) for _ in range(tools)]
    parked = _free_parked_configurations(arm, is_free)
    return Task(
        start=parked[rng.integers(len(parked))].copy(),
        poses=np.concatenate([cycles[g, c] for g, c in zip(grips, chosen, strict=True)])[
            :n_waypoints],
    )
