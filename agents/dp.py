"""Dynamic programming over the ladder graph (waypoints × branches) with the env's prices.

The graph's nodes are (waypoint i, branch k); the edges into waypoint i are the moves
``env.edge_rewards(i)`` prices: the reward ``step`` pays, collision penalties included,
and whether the move ends the episode. A terminal edge (the last waypoint, or a colliding
path with ``terminate_on_collision``) contributes its reward and nothing after it: the
env has already charged ``reward_unfinished`` for the waypoints it skips. Only valid
branches are edges (a baseline never picks a masked branch), so the optimum is over every
action sequence that respects the action mask.

Edges are priced lazily (LazySP: Dellin & Srinivasa, ICAPS 2016). Travel and time are
cheap and known for every edge; a collision check is not. An unchecked edge is priced as
if free, which never underprices it: a free move pays no penalty and, ending nothing,
leaves at least −(dearest move) per remaining waypoint, while a colliding one pays the
penalty and, when it ends the episode, exactly that much per skipped waypoint. So the
optimistic optimum bounds the true one from above. The planner takes the optimistic best
path, checks its unchecked edges (one batched call), and repeats until the best path has
none left: that path's return is exact and no other path can beat it. The plan and its
return equal those of pricing every edge (tested against brute force), with checks only
for edges that could still lie on the best path.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ikbranch_gym.envs.kinematics import compiled
from ikbranch_gym.envs.moves import TaskMoves

from .base import Baseline, first_within

Edges = tuple[np.ndarray, np.ndarray]  # reward (R, K), terminal (R, K)

#: Collision status of an edge in :class:`LazyLadder`.
UNKNOWN, FREE, COLLIDES = -1, 0, 1

_HERE = Path(__file__).resolve().parent


def cache_directory() -> Path | None:
    """Where this package's kernel is cached: a directory named by the hash of its sources
    (as the env's kernels, ``envs.kinematics.compiled.cached_njit``)."""
    return compiled.cache_directory(_HERE)


def _compiled(function: Callable) -> Any:
    # Without Python's lock, as the env's kernels (envs.jit): a vector env's groups plan
    # their resets' optimal returns in threads of their own.
    return compiled.cached_njit(function, cache_directory(), _HERE, nogil=True)


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


@_compiled
def _backward(
    reward: np.ndarray, terminal: np.ndarray, allowed: np.ndarray, q: np.ndarray
) -> None:
    """:func:`ladder_q_tables` on stacked (W, K, K) edges (row r of waypoint w: branch r
    of waypoint w − 1) into ``q``, with the same arithmetic, so the same values bit for
    bit."""
    count, k = reward.shape[0], reward.shape[2]
    after, value = np.zeros(k), np.empty(k)
    for w in range(count - 1, -1, -1):
        for r in range(k):
            best = -np.inf
            for b in range(k):
                total = reward[w, r, b] + (0.0 if terminal[w, r, b] else after[b])
                if not (allowed[w, b] and np.isfinite(total)):
                    total = -np.inf
                q[w, r, b] = total
                best = max(best, total)
            value[r] = best
        after[:] = value


def warm_up() -> None:
    """Compile (or load from numba's on-disk cache) the backward pass."""
    shape = (2, 2, 2)
    _backward(np.zeros(shape), np.zeros(shape, dtype=np.bool_), np.ones((2, 2), dtype=np.bool_),
              np.empty(shape))


def best_branch(q_row: np.ndarray, mask: np.ndarray) -> int:
    """argmax of a Q row over ``mask``, ties (within ``first_within``'s tolerance) to the lower
    branch index, as the rules break theirs.

    Exact argmax let rounding decide between branches of equal value: a wrist flip or a
    turn copy that the window cannot tell apart comes out ~1e-15 better or worse with the
    last bit of an IK solution, and receding_dp's returns moved by up to 4.0 on 12 of 200
    IRB2600Screwing-v0 tasks when IK rounding changed (docs/results.md)."""
    values = np.where(mask, q_row, -np.inf)
    if not np.isfinite(values).any():
        return int(np.argmax(values))
    return first_within(-values)


class LazyLadder:
    """A task's edges with collisions checked on demand (see the module docstring).

    Every edge's travel, time and both possible prices (free / colliding) are computed
    once, stacked (N, K, K): row r of waypoint i is candidate r of waypoint i − 1 (row 0 of
    waypoint 0 is the start, its other rows do not exist). ``status`` records which edges
    are checked and how.
    """

    def __init__(self, ladder: TaskMoves) -> None:
        self.ladder = ladder
        n, k = ladder.valid.shape
        self.origins, usable = ladder.stacked_origins()
        waypoints = np.arange(n)
        free = ladder.terms(self.origins, waypoints, collision=np.zeros((n, k, k), bool))
        hit = ladder.terms(self.origins, waypoints, collision=np.ones((n, k, k), bool))
        exists = usable[:, :, None]
        self._reward = {
            FREE: np.where(exists, free["reward"], np.nan),
            COLLIDES: np.where(exists, hit["reward"], np.nan),
        }
        self._terminal = {FREE: free["terminal"] | ~exists, COLLIDES: hit["terminal"] | ~exists}
        self.status = np.full((n, k, k), UNKNOWN, dtype=np.int8)
        self.status[~(exists & ladder.valid[:, None, :])] = FREE  # no move: nothing to check
        if ladder.task.free_start:  # the first step's collision is its branch's endpoint
            self.status[0, 0] = np.where(ladder.endpoint_collision[0], COLLIDES, FREE)
        self.checks = 0  # edges collision-checked so far

    def prices(self, first: int = 0, stop: int | None = None) -> Edges:
        """Stacked reward and terminal (W, K, K) of waypoints [first, stop), unchecked
        edges priced free."""
        window = slice(first, stop)
        hit = self.status[window] == COLLIDES
        return (np.where(hit, self._reward[COLLIDES][window], self._reward[FREE][window]),
                np.where(hit, self._terminal[COLLIDES][window], self._terminal[FREE][window]))

    def check(self, waypoints: np.ndarray, rows: np.ndarray, branches: np.ndarray) -> None:
        """Collision-check the edges (waypoint, row, branch), all in one call."""
        ladder = self.ladder
        starts = self.origins[waypoints, rows]
        ends = ladder.candidates[waypoints, branches]
        collides = ladder.pricer.paths_collide(starts, ends)
        self.status[waypoints, rows, branches] = np.where(collides, COLLIDES, FREE)
        self.checks += len(waypoints)

    def plan(self, first: int, stop: int, row: int,
             mask: np.ndarray | None = None) -> tuple[np.ndarray, list[int]]:
        """The best branch sequence over waypoints [first, stop) from origin ``row`` of
        waypoint ``first`` (choosing among ``mask`` there, default its valid branches),
        exactly priced: Q tables (W, K, K) of the final pass (exact along the plan, upper
        bounds elsewhere) and the plan (it stops at a terminal edge)."""
        valid = self.ladder.valid[first:stop].copy()
        if mask is not None:
            valid[0] &= mask
        q = np.empty((stop - first, *self.status.shape[1:]))
        while True:
            reward, terminal = self.prices(first, stop)
            _backward(reward, terminal, valid, q)
            plan, unchecked, r = [], [], row
            for w in range(stop - first):
                branch = best_branch(q[w, r], valid[w])
                plan.append(branch)
                if self.status[first + w, r, branch] == UNKNOWN:
                    unchecked.append((first + w, r, branch))
                if terminal[w, r, branch]:
                    break
                r = branch
            if not unchecked:
                return q, plan
            self.check(*np.array(unchecked).T)


def plan_episode(ladder: TaskMoves) -> tuple[LazyLadder, list[int], float]:
    """The optimal branch sequence of a whole episode from its start, over the lazily
    priced ladder, and its return summed forward as the env sums its rewards (replaying
    the plan through ``step`` pays exactly that). Returns the lazy ladder too (its checks
    serve later plans of the same episode)."""
    lazy = LazyLadder(ladder)
    _, plan = lazy.plan(0, ladder.task.n_waypoints, 0)
    reward, _ = lazy.prices()
    total, row = 0.0, 0
    for i, branch in enumerate(plan):
        total += float(reward[i, row, branch])
        row = branch
    return lazy, plan, total


class DPOracle(Baseline):
    """The global optimum of the whole episode, planned at reset with full knowledge.

    ``on_episode`` plans the whole episode over the lazily priced ladder (module
    docstring) and keeps the plan; each step follows it, and from a node off the plan (the
    arm was put elsewhere) it plans again from there, so the choice is optimal from any
    state. ``plan`` and ``planned_return`` are the optimal sequence from the start and its
    return, summed forward as the env sums rewards.
    """

    name = "dp_oracle"

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.lazy: LazyLadder | None = None
        self.plan: list[int] = []
        self.planned_return = float("nan")
        self._path: dict[tuple[int, int], int] = {}

    def on_episode(self) -> None:
        env = self.env
        assert env.task is not None and env.ladder is not None  # the env was just reset
        self.lazy, self.plan, self.planned_return = plan_episode(env.ladder)
        self._path, row = {}, 0
        for i, branch in enumerate(self.plan):
            self._path[(i, row)] = branch
            row = branch

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        row = self.current_row(waypoint)
        branch = self._path.get((waypoint, row))
        if branch is None or not mask[branch]:
            # Both set at the start of the episode (``on_episode``).
            assert self.lazy is not None and self.env.task is not None
            _, plan = self.lazy.plan(waypoint, self.env.task.n_waypoints, row, mask)
            return plan[0]
        return branch


class RecedingDP(Baseline):
    """The same DP over only the next ``horizon`` waypoints, re-planned every step.

    ``horizon`` counts the next waypoint too; it defaults to ``env.lookahead + 1``, the
    waypoints a learned policy sees in its observation, which makes this the fair analytic
    rival of such a policy (it still sees every path collision in the window, where the
    observation shows path collisions for the next waypoint only). With
    ``horizon >= n_waypoints`` it is :class:`DPOracle`. Edges are priced lazily, and a
    checked edge stays checked for the episode.
    """

    name = "receding_dp"

    def __init__(self, env: gym.Env, horizon: int | None = None) -> None:
        super().__init__(env)
        horizon = self.env.lookahead + 1 if horizon is None else horizon
        if not isinstance(horizon, int | np.integer) or horizon < 1:
            raise ValueError(f"horizon must be an integer >= 1, got {horizon!r}")
        self.horizon = int(horizon)
        self.lazy: LazyLadder | None = None

    def on_episode(self) -> None:
        assert self.env.ladder is not None  # the env was just reset
        self.lazy = LazyLadder(self.env.ladder)

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        # Both set at the start of the episode (``on_episode``).
        assert self.lazy is not None and self.env.task is not None
        stop = min(waypoint + self.horizon, self.env.task.n_waypoints)
        _, plan = self.lazy.plan(waypoint, stop, self.current_row(waypoint), mask)
        return plan[0]
