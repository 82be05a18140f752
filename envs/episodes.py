"""Episodes in a batch: the state of B episodes of one env and how it advances.

``IKBranchEnv`` runs a batch of one, ``IKBranchVectorEnv`` a batch of one row per sub-env:
the same arrays and the same calls, so a sub-env is its single env bit for bit. Each stage
handles every row it is given at once:

- :meth:`EpisodeBatch.begin` — a row takes a new task: its ladder (candidates, validity,
  endpoint hits) and observation templates, the arm at the task's start;
- :meth:`EpisodeBatch.survey` — for rows in a new state, the moves into their next
  waypoint: every path from where the arm stands (one ``paths_collide`` call for all
  rows), every price (one :func:`envs.moves._price` call), the least free travel onward
  (one call per round, :func:`envs.moves.least_free_travel`) and the observation (one
  assembly);
- :meth:`EpisodeBatch.advance` — rows take their actions: what :meth:`survey` priced for
  the chosen branches is paid, and the arm moves.

Where the path verdicts come from is the owner's: the single env's checker through its
cache (``MovePricer.paths_collide``), a vector env's stacked scenes in one kernel call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.moves import REWARD_TERMS, LinePaths, MovePricer, TaskMoves, _price, least_free_travel
from envs.observations import ObservationBuilder


@dataclass(frozen=True)
class Steps:
    """What :meth:`EpisodeBatch.advance` paid, per advanced row (arrays of that length):
    the waypoint moved into, the branch, the reward and its terms, travel and time, the
    move's collision and invalidity, whether it ended the episode and, where it did,
    whether the episode succeeded."""

    waypoint: np.ndarray
    branch: np.ndarray
    reward: np.ndarray
    travel: np.ndarray
    time: np.ndarray
    terms: dict[str, np.ndarray]
    collision: np.ndarray
    invalid: np.ndarray
    terminated: np.ndarray
    success: np.ndarray

    def info(self, i: int) -> dict:
        """Row ``i``'s ``info`` as a single env reports it: Python numbers, in this order."""
        info = {"waypoint": int(self.waypoint[i]), "branch": int(self.branch[i]),
                "travel": float(self.travel[i]), "time": float(self.time[i])}
        info.update((name, float(value[i])) for name, value in self.terms.items())
        info["collision"], info["invalid"] = bool(self.collision[i]), bool(self.invalid[i])
        if self.terminated[i]:
            info["is_success"] = bool(self.success[i])
        return info


class EpisodeBatch:
    """The state of ``size`` episodes of tasks of ``n_waypoints`` waypoints each, for one
    pricer (arm, cost, penalties) and one observation layout; ``paths_collide`` gives the
    path verdicts of a row's moves (``envs.moves.LinePaths``: lines are rows)."""

    def __init__(self, size: int, n_waypoints: int, pricer: MovePricer,
                 observations: ObservationBuilder, paths_collide: LinePaths) -> None:
        arm = pricer.arm
        k, dof, n = arm.n_branches, arm.dof, n_waypoints
        self.size, self.n_waypoints, self.pricer = size, n_waypoints, pricer
        self.observations, self.paths_collide = observations, paths_collide
        #: Per row: the configuration, the next waypoint (``n_waypoints`` once over), and
        #: whether a move of the episode collided or picked an invalid branch.
        self.q = np.zeros((size, dof))
        self.index = np.full(size, n, dtype=np.int64)
        self.collided = np.zeros(size, dtype=bool)
        self.invalid = np.zeros(size, dtype=bool)
        #: Per row: its task's ladder and observation templates.
        self.candidates = np.full((size, n, k, dof), np.nan)
        self.valid = np.zeros((size, n, k), dtype=bool)
        self.endpoint = np.zeros((size, n, k), dtype=bool)
        self.start = np.zeros((size, dof))
        self.free_start = np.zeros(size, dtype=bool)
        self.templates = np.zeros((size, n + 1, observations.size), dtype=np.float32)
        #: Per row: the priced moves of its current state into its next waypoint, as
        #: ``_price`` writes them (value and flag blocks of (row, 1, K)), and its
        #: observation.
        self.values = np.zeros((len(_VALUE_NAMES), size, 1, k))
        self.flags = np.zeros((3, size, 1, k), dtype=bool)
        self.observation = np.zeros((size, observations.size), dtype=np.float32)
        self._lengths = np.full(size, n, dtype=np.int64)

    #: The per-row arrays (a view of one row shares them).
    _ROW_ARRAYS = ("q", "index", "collided", "invalid", "candidates", "valid", "endpoint",
                   "start", "free_start", "templates", "observation", "_lengths")

    def view(self, row: int, paths_collide: LinePaths) -> EpisodeBatch:
        """A batch of one whose arrays are row ``row`` of this batch's: what either does to
        the row, the other sees (a vector env's sub-env runs its episode in its row)."""
        one = object.__new__(EpisodeBatch)
        one.size, one.n_waypoints, one.pricer = 1, self.n_waypoints, self.pricer
        one.observations, one.paths_collide = self.observations, paths_collide
        for name in self._ROW_ARRAYS:
            setattr(one, name, getattr(self, name)[row : row + 1])
        one.values, one.flags = self.values[:, row : row + 1], self.flags[:, row : row + 1]
        return one

    # ------------------------------------------------------------------------- stages
    def begin(self, row: int, ladder: TaskMoves, templates: np.ndarray) -> None:
        """Row ``row`` starts ``ladder``'s task (its templates from ``ObservationBuilder``)."""
        if ladder.n_waypoints != self.n_waypoints:
            raise ValueError(f"a task of {ladder.n_waypoints} waypoints in a batch of "
                             f"{self.n_waypoints}")
        self.candidates[row], self.valid[row] = ladder.candidates, ladder.valid
        self.endpoint[row], self.templates[row] = ladder.endpoint_collision, templates
        self.start[row] = ladder.task.start
        self.free_start[row] = ladder.task.free_start
        self.q[row] = ladder.task.start
        self.index[row] = 0
        self.collided[row] = self.invalid[row] = False

    def survey(self, rows: np.ndarray) -> None:
        """Price the moves of ``rows`` (int array) from their current state and assemble
        their observations (``self.observation[rows]``)."""
        live = rows[self.index[rows] < self.n_waypoints]
        collision = self._slot_paths(live)
        if len(live):
            self._price(live, collision)
        onward = None
        if self.observations.wants_onward:
            onward = self._onward(live, self.valid[live, self.index[live]] & ~collision)
        self.observation[rows] = self.observations.observe_rows(
            self.templates[rows], self.index[rows], self.q[rows])
        if len(live):
            self.observations.fill_slot0(
                self.observation, live, self.valid[live, self.index[live]],
                self.values[1, live, 0], collision, onward)

    def advance(self, rows: np.ndarray, actions: np.ndarray) -> Steps:
        """Rows ``rows`` move to branch ``actions`` (ints in [0, K), checked by the caller)
        of their next waypoint, paying what :meth:`survey` priced."""
        waypoint = self.index[rows]
        values = self.values[:, rows, 0, actions]
        flags = self.flags[:, rows, 0, actions]
        terminated, collision, invalid = flags
        moved = rows[~invalid]
        self.q[moved] = self.candidates[moved, waypoint[~invalid], actions[~invalid]]
        self.index[rows] = np.where(terminated, self.n_waypoints, waypoint + 1)
        self.collided[rows] |= collision
        self.invalid[rows] |= invalid
        success = (terminated & (waypoint == self.n_waypoints - 1) & ~self.collided[rows]
                   & ~self.invalid[rows])
        terms = {name: values[3 + i] for i, name in enumerate(REWARD_TERMS)}
        return Steps(waypoint=waypoint, branch=actions, reward=values[0], travel=values[1],
                     time=values[2], terms=terms, collision=collision, invalid=invalid,
                     terminated=terminated, success=success)

    def masks(self, rows: np.ndarray) -> np.ndarray:
        """(len(rows), K) bool: the valid branches of each row's next waypoint; every
        branch once its episode is over (any action then, as the env allows)."""
        over = self.index[rows] >= self.n_waypoints
        waypoint = np.minimum(self.index[rows], self.n_waypoints - 1)
        return self.valid[rows, waypoint] | over[:, None]

    # ----------------------------------------------------------------------- helpers
    def _slot_paths(self, live: np.ndarray) -> np.ndarray:
        """(len(live), K) bool: the move from each row's configuration to each valid branch
        of its next waypoint collides (its path; at a free start the branch's own
        configuration); invalid branches are False. One ``paths_collide`` call."""
        waypoint = self.index[live]
        valid = self.valid[live, waypoint]
        collision = np.zeros(valid.shape, dtype=bool)
        still = self.free_start[live] & (waypoint == 0)
        collision[still] = self.endpoint[live[still], 0] & valid[still]
        lines, branches = np.nonzero(valid & ~still[:, None])
        if len(lines):
            ends = self.candidates[live[lines], waypoint[lines], branches]
            collision[lines, branches] = self.paths_collide(live[lines], self.q[live[lines]],
                                                            ends)
        return collision

    def _price(self, live: np.ndarray, collision: np.ndarray) -> None:
        """Every term of every move of ``live`` rows (``_price``, one call)."""
        waypoint = self.index[live]
        values = np.empty((len(_VALUE_NAMES), len(live), 1, self.valid.shape[2]))
        flags = np.empty((3, len(live), 1, self.valid.shape[2]), dtype=bool)
        _price(self.q[live][:, None], self.candidates[live, waypoint], self.valid[live, waypoint],
               waypoint, collision[:, None], self.free_start[live], self._lengths[live],
               *self.pricer.price_arguments, values, flags)
        self.values[:, live], self.flags[:, live] = values, flags

    def _onward(self, live: np.ndarray, branches: np.ndarray) -> np.ndarray:
        """(len(live), K): per branch of each row's next waypoint that ``branches`` allows,
        the least travel onward along a free path (+inf where none, and at the last
        waypoint)."""
        onward = np.full(branches.shape, np.inf)
        inner = np.flatnonzero(self.index[live] + 1 < self.n_waypoints)
        if not len(inner):
            return onward
        rows, here = live[inner], self.index[live[inner]]
        targets = self.valid[rows, here + 1] & ~self.endpoint[rows, here + 1]
        onward[inner] = least_free_travel(
            self.candidates[rows, here], self.candidates[rows, here + 1], branches[inner],
            targets, self.pricer.cost.weights,
            lambda lines, starts, ends: self.paths_collide(rows[lines], starts, ends))
        return onward


#: Rows of ``EpisodeBatch.values``: as ``envs.moves._price`` writes them.
_VALUE_NAMES = ("reward", "travel", "time", *REWARD_TERMS)
