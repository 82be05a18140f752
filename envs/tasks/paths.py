"""Path following: waypoints along a helix, a circle or a line (Klyuiko's eq. 7).

The object point runs along r(t); the gripper's x, y, z axes follow the tangent, principal
normal and binormal (``frenet_pose``), with the wrist centre ``TOOL_OFFSET`` behind the
point along y. A straight line has no principal normal: there the orientation stays that
of the configuration the line starts from. Each candidate path is placed around the wrist
centre of a random collision-free configuration and kept only if every waypoint has a
valid, collision-free branch.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ikbranch_gym.envs.kinematics import Arm, frenet_pose

from .base import (
    FreePredicate,
    PathPredicate,
    Task,
    require_pose_arm,
    sample_free_configurations,
    task_generator,
)

#: b of eq. 7 (m): object point ahead of the wrist centre along the gripper's y axis.
TOOL_OFFSET = 0.1
#: Attempts at placing a path before giving up.
MAX_ATTEMPTS = 200


def _reachable(arm: Arm, poses: np.ndarray, is_free: FreePredicate) -> bool:
    solutions, valid = arm.ik(poses)
    if not valid.any(axis=-1).all():
        return False
    free = np.zeros(valid.shape, dtype=bool)
    free[valid] = is_free(solutions[valid])
    return bool(free.any(axis=-1).all())


def _place(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    make_poses: Callable[[np.ndarray, int, np.random.Generator], np.ndarray],
) -> Task:
    for _ in range(MAX_ATTEMPTS):
        anchor = sample_free_configurations(arm, rng, 2, is_free)
        poses = make_poses(arm.fk(anchor[1]), n_waypoints, rng)
        if _reachable(arm, poses, is_free):
            return Task(start=anchor[0], poses=poses)
    raise RuntimeError(f"{arm.name}: no reachable path found in {MAX_ATTEMPTS} attempts")


def _helical_poses(
    anchor: np.ndarray, radius: float, pitch: float, phase: float, t: np.ndarray
) -> np.ndarray:
    """Frenet poses along the helix through the anchor's wrist centre at angle ``phase``
    (a circle when ``pitch`` is 0), at the angles ``t``."""
    centre = anchor[:3, 3] - radius * np.array([np.cos(phase), np.sin(phase), 0.0])
    rise = np.full_like(t, pitch)
    points = centre + np.stack([radius * np.cos(t), radius * np.sin(t), pitch * (t - phase)], -1)
    velocity = np.stack([-radius * np.sin(t), radius * np.cos(t), rise], -1)
    acceleration = np.stack([-radius * np.cos(t), -radius * np.sin(t), np.zeros_like(t)], -1)
    return frenet_pose(points, velocity, acceleration, TOOL_OFFSET)


def _helix_poses(anchor: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    radius, pitch = rng.uniform(0.08, 0.25), rng.uniform(-0.15, 0.15)
    phase, turns = rng.uniform(0, 2 * np.pi), rng.uniform(0.5, 1.0)
    t = phase + np.linspace(0.0, 2 * np.pi * turns, n)
    return _helical_poses(anchor, radius, pitch, phase, t)


@task_generator(default_waypoints=8, check_arm=require_pose_arm)
def helix(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """A helix of random radius (0.08–0.25 m), pitch and length (½–1 turn)."""
    return _place(arm, rng, n_waypoints, is_free, _helix_poses)


def _circle_poses(anchor: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    radius, phase = rng.uniform(0.08, 0.25), rng.uniform(0, 2 * np.pi)
    t = phase + np.linspace(0.0, 2 * np.pi * (n - 1) / n, n)
    return _helical_poses(anchor, radius, 0.0, phase, t)


@task_generator(default_waypoints=8, check_arm=require_pose_arm)
def circle(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """A horizontal circle of random radius (0.08–0.25 m), evenly sampled."""
    return _place(arm, rng, n_waypoints, is_free, _circle_poses)


def _line_poses(anchor: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    length = rng.uniform(0.2, 0.6)
    poses = np.repeat(anchor[None], n, axis=0)
    poses[:, :3, 3] += np.linspace(0.0, length, n)[:, None] * direction
    return poses


@task_generator(default_waypoints=8, check_arm=require_pose_arm)
def line(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """A straight segment (0.2–0.6 m, random direction) at constant orientation."""
    return _place(arm, rng, n_waypoints, is_free, _line_poses)
