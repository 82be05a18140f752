"""Predicates and checks shared by the task-generator tests."""

from __future__ import annotations

import numpy as np

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.tasks import Task


def half_space(arm: Arm):
    """A deterministic, convex 'obstacle': configurations with φ1/s1 below mid-range collide
    (so generators must ask the predicate, and straight joint-space sweeps between free
    configurations stay free)."""
    middle = arm.joint_limits[0].mean()

    def is_free(q, need=None):
        return np.asarray(q)[..., 0] >= middle

    return is_free


def all_paths_free(q0, q1):
    """A path predicate for scenes where only configurations can collide."""
    return np.ones(len(np.asarray(q0)), dtype=bool)


def assert_same_task(a: Task, b: Task) -> None:
    assert np.array_equal(a.start, b.start) and np.array_equal(a.poses, b.poses)
    assert a.free_start == b.free_start


def assert_every_waypoint_has_a_free_branch(arm: Arm, task: Task, is_free) -> None:
    candidates, valid = arm.ik(task.poses)
    free = np.zeros_like(valid)
    free[valid] = is_free(candidates[valid])
    assert free.any(axis=-1).all()
    assert task.start.shape == (arm.dof,) and np.all(is_free(task.start[None]))


def everywhere_free(q, need=None):
    """A free predicate for an empty scene."""
    return np.ones(len(q), dtype=bool)


def nowhere_free(q, need=None):
    """A free predicate for a scene with no room at all."""
    return np.zeros(len(q), dtype=bool)
