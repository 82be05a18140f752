"""The milling cell's tasks: the paper's transfer, and sequences of tool changes."""

from __future__ import annotations

import numpy as np

from envs.kinematics import Arm
from envs.kinematics.paper_example import example_poses, rack_slot_poses

from .base import FreePredicate, Task, task_generator


def _require_anthropomorphic(arm: Arm, scene: str) -> None:
    if arm.name != "anthropomorphic":
        raise ValueError(f"the milling-cell tasks need the anthropomorphic arm, not {arm.name!r}")


def _require_cell(arm: Arm, scene: str) -> None:
    _require_anthropomorphic(arm, scene)
    if scene != "milling_cell":
        raise ValueError("tool_changes needs scene='milling_cell' (its rack and spindle)")


@task_generator(default_waypoints=2, check_arm=_require_anthropomorphic)
def paper_transfer(
    arm: Arm, rng: np.random.Generator, n_waypoints: int, is_free: FreePredicate
) -> Task:
    """Klyuiko's worked example: the arm stands at position 1 with a free choice of its
    branch (the first step costs no motion), then transfers to position 2. The least
    total travel is the paper's 275.15°."""
    if n_waypoints != 2:
        raise ValueError("paper_transfer has exactly 2 waypoints (positions 1 and 2)")
    return Task(start=arm.home, poses=example_poses(), free_start=True)


@task_generator(default_waypoints=6, check_arm=_require_cell)
def tool_changes(
    arm: Arm, rng: np.random.Generator, n_waypoints: int, is_free: FreePredicate
) -> Task:
    """From home, alternate between a random rack slot and the spindle: fetch a tool from
    a slot, put it in the spindle, take it back to a (random) slot, … The spindle pose is
    the paper's position 2; slot 0 is its position 1."""
    slots, spindle = rack_slot_poses(), example_poses()[1]
    poses = np.empty((n_waypoints, 4, 4))
    poses[1::2] = spindle
    poses[0::2] = slots[rng.integers(len(slots), size=len(poses[0::2]))]
    return Task(start=arm.home, poses=poses)
