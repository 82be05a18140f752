"""Dynamic programming over the ladder graph (waypoints × branches) with the env's prices.

The graph's nodes are (waypoint i, branch k); the edges into waypoint i are exactly
``env.edge_rewards(i)``: the reward ``step`` pays, collision penalties included, and
whether the move ends the episode. A terminal edge (the last waypoint, or a colliding path
with ``terminate_on_collision``) contributes its reward and nothing after it: the env has
already charged ``reward_unfinished`` for the waypoints it skips. Only valid branches are
edges (a baseline never picks a masked branch), so the optimum is over every action
sequence that respects the action mask.
"""

from __future__ import annotations

from collections.abc import Sequence

import gymnasium as gym
import numpy as np

from .base import Baseline

Edges = tuple[np.ndarray, np.ndarray]  # reward (R, K), terminal (R, K)


def ladder_q_tables(edges: Sequence[Edges], allowed: np.ndarray) -> list[np.ndarray]:
    """Backward induction over consecutive waypoints.

    ``edges[w]`` prices the moves into the w-th waypoint of the window (rows: where the arm
    stands before it; NaN rows for configurations that do not exist), ``allowed`` (W, K)
    the branches that may be chosen. Returns Q tables: ``q[w][r, k]`` is the best return
    from standing in row r before waypoint w and choosing branch k (−inf where k is not
    allowed or row r does not exist), counting the window only: after its last waypoint
    the value is 0 (the episode ends there, or a receding horizon stops looking).
    """
    if len(edges) != len(allowed):
        raise ValueError("one allowed row per waypoint of the window")
    tables: list[np.ndarray] = [np.empty(0)] * len(edges)
    after = np.zeros(allowed.shape[-1])  # V of each branch of the window's last waypoint
    for w in range(len(edges) - 1, -1, -1):
        reward, terminal = edges[w]
        q = reward + np.where(terminal, 0.0, after[None, :])
        q = np.where(allowed[w][None, :] & np.isfinite(q), q, -np.inf)
        tables[w] = q
        after = q.max(axis=1)
    return tables


def best_branch(q_row: np.ndarray, mask: np.ndarray) -> int:
    """argmax of a Q row over ``mask``; exact ties go to the lower branch index."""
    return int(np.argmax(np.where(mask, q_row, -np.inf)))


class DPOracle(Baseline):
    """The global optimum of the whole episode, planned at reset with full knowledge.

    ``on_episode`` prices every edge (``edge_rewards`` for every waypoint, every path
    collision-checked; the env caches them) and runs the backward pass once; each step then
    reads its Q table at the node the arm stands in, so the plan is also right from any
    state the arm was put in. ``plan`` and ``planned_return`` are the optimal sequence from
    the start and its return, summed forward as the env sums rewards.
    """

    name = "dp_oracle"

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.q_tables: list[np.ndarray] = []
        self.plan: list[int] = []
        self.planned_return = float("nan")

    def on_episode(self) -> None:
        env = self.env
        edges = [env.edge_rewards(i) for i in range(env.task.n_waypoints)]
        self.q_tables = ladder_q_tables(edges, env.valid)
        self.plan, self.planned_return = [], 0.0
        row = 0
        for i, (reward, terminal) in enumerate(edges):
            branch = best_branch(self.q_tables[i][row], env.valid[i])
            self.plan.append(branch)
            self.planned_return += float(reward[row, branch])
            if terminal[row, branch]:
                break
            row = branch

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        return best_branch(self.q_tables[waypoint][self.current_row(waypoint)], mask)


class RecedingDP(Baseline):
    """The same DP over only the next ``horizon`` waypoints, re-planned every step.

    ``horizon`` counts the next waypoint too; it defaults to ``env.lookahead + 1``, the
    waypoints a learned policy sees in its observation, which makes this the fair analytic
    rival of such a policy (it still sees every path collision in the window, where the
    observation shows path collisions for the next waypoint only). With
    ``horizon >= n_waypoints`` it is :class:`DPOracle`. Edge prices are cached per episode.
    """

    name = "receding_dp"

    def __init__(self, env: gym.Env, horizon: int | None = None) -> None:
        super().__init__(env)
        horizon = self.env.lookahead + 1 if horizon is None else horizon
        if not isinstance(horizon, int | np.integer) or horizon < 1:
            raise ValueError(f"horizon must be an integer >= 1, got {horizon!r}")
        self.horizon = int(horizon)
        self._edges: dict[int, Edges] = {}

    def on_episode(self) -> None:
        self._edges = {}

    def _edge(self, waypoint: int) -> Edges:
        if waypoint not in self._edges:
            self._edges[waypoint] = self.env.edge_rewards(waypoint)
        return self._edges[waypoint]

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        env = self.env
        stop = min(waypoint + self.horizon, env.task.n_waypoints)
        edges = [self._edge(i) for i in range(waypoint, stop)]
        tables = ladder_q_tables(edges, env.valid[waypoint:stop])
        return best_branch(tables[0][self.current_row(waypoint)], mask)
