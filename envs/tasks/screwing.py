"""Screwing: the tool turns about its own axis, far past one revolution."""

from __future__ import annotations

import numpy as np

from ikbranch_gym.envs.kinematics import Arm

from .base import (
    FreePredicate,
    PathPredicate,
    Task,
    require_pose_arm,
    sample_free_configurations,
    task_generator,
)

#: Turn per waypoint (rad), drawn uniformly: 60° to 100°, so 8 waypoints turn 420° to 700°
#: in all: within the ±400° of the ABB arms' last joint, if the first branch leaves room.
STEP_RANGE = (np.pi / 3, 5 * np.pi / 9)


@task_generator(default_waypoints=8, check_arm=require_pose_arm)
def screwing(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """A nut runner on a fixed screw: the arm stands at the screw (the first step only
    picks its branch, at no cost, as the paper's transfer starts in the rack), then the
    tool turns about its own axis (the task frame's z: the flange normal of the industrial
    arms) by the same random step Δ ∈ [60°, 100°] at every waypoint, one way: (N − 1)·Δ in
    all, 420° to 700° at the default 8 waypoints. The last wrist joint follows the screw.
    Its limits (±400° on the ABB arms) hold the whole screw only if the first branch's
    turn window leaves room in the screw's direction: a branch picked for its index (or
    for the least travel so far) may force a 360° unwinding on the way. The screw stands
    at the pose of a random collision-free configuration, so its start branch reaches
    every waypoint unless a joint limit forbids it."""
    anchor = sample_free_configurations(arm, rng, 1, is_free)[0]
    step = rng.uniform(*STEP_RANGE) * rng.choice((-1.0, 1.0))
    angles = step * np.arange(n_waypoints)
    turn = np.zeros((n_waypoints, 4, 4))
    turn[:, 0, 0] = turn[:, 1, 1] = np.cos(angles)
    turn[:, 0, 1], turn[:, 1, 0] = -np.sin(angles), np.sin(angles)
    turn[:, 2, 2] = turn[:, 3, 3] = 1.0
    return Task(start=anchor, poses=arm.fk(anchor) @ turn, free_start=True)
