"""Random reachable waypoints: the FK of random collision-free configurations."""

from __future__ import annotations

import numpy as np

from envs.kinematics import Arm

from .base import FreePredicate, Task, sample_free_configurations, task_generator


@task_generator(default_waypoints=8)
def random_reachable(
    arm: Arm, rng: np.random.Generator, n_waypoints: int, is_free: FreePredicate
) -> Task:
    """Start and waypoints from configurations drawn inside the limits, collision-free.

    Each waypoint's own configuration is one of its IK branches, so at least one branch is
    valid and collision-free at the waypoint (the path there may still collide).
    """
    configurations = sample_free_configurations(arm, rng, n_waypoints + 1, is_free)
    return Task(start=configurations[0], poses=arm.fk(configurations[1:]))
