"""The best return of a task by enumerating every action sequence: what the DP oracle
must equal (tests/agents/test_dp.py on small tasks, tests/train/test_results.py on the
published ones)."""

from __future__ import annotations

import numpy as np


def brute_force(env) -> float:
    """The best return over every mask-respecting action sequence, from the price table.

    All K^N sequences are held at once, one array entry each, and walked forward a
    waypoint at a time; none is merged with another or dropped (that would be the DP under
    test). A terminal edge ends a sequence: it pays nothing more, whatever it picks after.
    """
    n, k = env.task.n_waypoints, env.arm.n_branches
    total = np.zeros(1)  # the return of each sequence so far
    alive = np.ones(1, dtype=bool)  # not ended yet
    row = np.zeros(1, dtype=np.int64)  # where it stands: the one start row, then a branch
    for waypoint in range(n):
        reward, terminal = env.edge_rewards(waypoint)
        count = total.size
        total, alive, row = np.repeat(total, k), np.repeat(alive, k), np.repeat(row, k)
        branch = np.tile(np.arange(k), count)
        moves = alive & env.valid[waypoint, branch]
        total[alive & ~moves] = -np.inf  # a masked branch: not a sequence a policy may play
        total[moves] += reward[row[moves], branch[moves]]
        alive = moves & ~terminal[row, branch]
        row = branch
    return float(total.max())
