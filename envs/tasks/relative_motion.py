"""Two-arm relative-motion profiles (Vorob'ev 2020): M34(t) sampled into waypoints."""

from __future__ import annotations

import numpy as np

from ikbranch_gym.envs.kinematics import Arm

from .base import FreePredicate, PathPredicate, Task, sample_free_configurations, task_generator

#: Attempts at a profile whose every sample is collision-free before accepting one that
#: is not (its waypoints stay reachable; only some branches then collide).
MAX_ATTEMPTS = 50


def _require_dual(arm: Arm, scene: str) -> None:
    if not arm.relative:
        raise ValueError(f"relative_motion needs a two-arm system, not {arm.name!r}")


@task_generator(default_waypoints=8, check_arm=_require_dual)
def relative_motion(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """The relative pose of link 4 in link 3 along a smooth joint-space sweep.

    Both arms move from one collision-free configuration of the pair to another along a
    cosine-eased straight line in joint space; the task is the relative pose M34 = fk(q(t))
    at ``n_waypoints`` instants, so every waypoint is reachable by construction. The agent
    is free to realise each with another branch, which is the point.

    Only the sweep's sampled configurations are checked, not the straight paths between
    them (unlike ``random``): some tasks have no collision-free solution (the oracle
    succeeds on 86 % of DualRRPRPP-v0's published tasks, 98–100 % on the other two).
    """
    return _sweep(arm, rng, n_waypoints, is_free, None)


@task_generator(default_waypoints=8, check_arm=_require_dual)
def relative_motion_free(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """``relative_motion`` whose whole sweep is a collision-free straight path: every
    waypoint's sweep configuration lies on the line from start to end, so one path check
    of that line makes the sweep itself a solution that never collides (the v1 dual-arm
    ids; a perfect policy succeeds on every task)."""
    return _sweep(arm, rng, n_waypoints, is_free, is_path_free)


def _sweep(arm: Arm, rng: np.random.Generator, n_waypoints: int, is_free: FreePredicate,
           is_path_free: PathPredicate | None) -> Task:
    t = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, n_waypoints + 1))[1:, None]
    for _ in range(MAX_ATTEMPTS):
        start, end = sample_free_configurations(arm, rng, 2, is_free)
        profile = start + t * (end - start)
        if not is_free(profile).all():
            continue
        if is_path_free is None or is_path_free(start[None], end[None])[0]:
            return Task(start=start, poses=arm.fk(profile))
    if is_path_free is not None:
        raise RuntimeError(f"{arm.name}: no collision-free sweep in {MAX_ATTEMPTS} attempts")
    return Task(start=start, poses=arm.fk(profile))
