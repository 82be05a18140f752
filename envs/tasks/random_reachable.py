"""Random reachable waypoints: the FK of a random collision-free chain of configurations."""

from __future__ import annotations

import numpy as np

from ikbranch_gym.envs.kinematics import Arm

from .base import (
    FreePredicate,
    PathPredicate,
    Task,
    sample_free_configurations,
    task_generator,
)

#: Fresh draws for one waypoint before the configuration it starts from is redrawn too (a
#: configuration tucked in among obstacles may have no free straight path out).
REDRAWS_BEFORE_BACKTRACK = 20
#: Fresh draws in all before the scene is declared too crowded.
MAX_DRAWS = 2000


@task_generator(default_waypoints=8)
def random_reachable(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
) -> Task:
    """Start and waypoints from a chain of configurations drawn inside ``arm``'s
    ``joint_limits`` (an env's ``task_joint_range`` where it has one: ``RangedArm``).

    Every configuration is collision-free and so is the straight joint-space path from each
    to the next: a draw whose path from the previous one collides is replaced by a fresh
    draw, and after ``REDRAWS_BEFORE_BACKTRACK`` failures the previous one is redrawn too.
    Each waypoint's own configuration is one of its IK branches, so the chain is a solution
    of the task that never collides: a perfect policy succeeds on every task (the optimum
    may still take other branches).
    """
    chain = list(sample_free_configurations(arm, rng, n_waypoints + 1, is_free))
    index, tries, draws = 1, 0, 0
    verdicts: dict[int, bool] = {}  # index i -> the path chain[i - 1] -> chain[i] is free
    while index <= n_waypoints:
        if index not in verdicts:
            # In one call the link the walk stands at and every unchecked one after the
            # next: a redraw here changes the next link's start, so a check of it now
            # would be wasted wherever this one collides. A link's verdict does not depend
            # on when it is checked: the walk is the same as checking one at a time.
            links = [index, *(i for i in range(index + 2, n_waypoints + 1)
                              if i not in verdicts)]
            free = is_path_free(np.array([chain[i - 1] for i in links]),
                                np.array([chain[i] for i in links]))
            verdicts.update(zip(links, free.tolist(), strict=True))
        if verdicts[index]:
            index, tries = index + 1, 0
            continue
        draws += 1
        if draws > MAX_DRAWS:
            raise RuntimeError(
                f"{arm.name}: no chain of collision-free paths after {MAX_DRAWS} draws; "
                "the scene leaves too little free space"
            )
        tries += 1
        if tries >= REDRAWS_BEFORE_BACKTRACK:
            tries = 0
            if index > 1:
                index -= 1  # redraw the configuration we came from (checked again below)
            else:
                chain[0] = sample_free_configurations(arm, rng, 1, is_free)[0]
                verdicts.pop(1, None)
                continue
        chain[index] = sample_free_configurations(arm, rng, 1, is_free)[0]
        verdicts.pop(index, None)
        verdicts.pop(index + 1, None)
    return Task(start=chain[0], poses=arm.fk(np.array(chain[1:])))
