"""Random reachable waypoints: the FK of a random collision-free chain of configurations."""

from __future__ import annotations

import numpy as np

from envs.kinematics import Arm

from .base import (
    FreePredicate,
    PathPredicate,
    Task,
    sample_free_configurations,
    task_generator,
)

#: Fresh draws tried for one waypoint before the chain is given up as stuck.
MAX_REDRAWS = 100


@task_generator(default_waypoints=8)
def random_reachable(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """Start and waypoints from a chain of configurations drawn inside the limits.

    Every configuration is collision-free and so is the straight joint-space path from each
    to the next (a draw whose path from the previous one collides is replaced by a fresh
    draw). Each waypoint's own configuration is one of its IK branches, so the chain is a
    solution of the task that never collides: a perfect policy succeeds on every task
    (the optimum may still take other branches).
    """
    chain = list(sample_free_configurations(arm, rng, n_waypoints + 1, is_free))
    for index in range(1, n_waypoints + 1):
        for _ in range(MAX_REDRAWS):
            if is_path_free(chain[index - 1][None], chain[index][None])[0]:
                break
            chain[index] = sample_free_configurations(arm, rng, 1, is_free)[0]
        else:
            raise RuntimeError(
                f"{arm.name}: no collision-free path out of waypoint {index - 1} in "
                f"{MAX_REDRAWS} draws; the scene leaves too little free space"
            )
    return Task(start=chain[0], poses=arm.fk(np.array(chain[1:])))
