"""Episodes in a batch: the state of B episodes of one env and how it advances.

``IKBranchEnv`` runs a batch of one, ``IKBranchVectorEnv`` a batch of one row per sub-env:
the same arrays and the same calls, so a sub-env is its single env bit for bit. Each stage
handles every row it is given at once:

- :meth:`EpisodeBatch.begin` — a row takes a new task: its ladder (candidates, validity,
  endpoint hits) and observation templates, the arm at the task's start;
- :meth:`EpisodeBatch.survey` — for rows in a new state, the moves into their next
  waypoint, their prices, the least free travel onward (of one move, and of several
  where the layout shows it) and the observations;
- :meth:`EpisodeBatch.advance` — rows take their actions: what :meth:`survey` priced for
  the chosen branches is paid, and the arm moves.

Both are one compiled call each (``envs.stepping``), whatever the number of rows; the
paths are decided by the compiled collision filter, each in its row's scene (the single
env's own filter, a vector env's stacked scenes), through a memo of path verdicts.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ikbranch_gym.envs import stepping
from ikbranch_gym.envs.models.filter import CompiledFilter, FilterStack
from ikbranch_gym.envs.moves import REWARD_TERMS, MovePricer, TaskMoves
from ikbranch_gym.envs.observations import ObservationBuilder

#: Scene tokens of this process: each scene laid gets its own (``EpisodeBatch.set_scene``).
_SCENE_TOKENS = itertools.count(1)


def new_scene_token() -> int:
    """A token no scene of this process has had (0 is a fixed scene's)."""
    return next(_SCENE_TOKENS)


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
    pricer (arm, cost, penalties) and one observation layout; ``checks`` is the compiled
    collision filter (a ``CompiledFilter``, or a ``FilterStack`` with ``scenes`` naming
    each row's scene in it) that decides the paths of the rows' moves."""

    def __init__(self, size: int, n_waypoints: int, pricer: MovePricer,
                 observations: ObservationBuilder, checks: CompiledFilter | FilterStack,
                 scenes: np.ndarray | None = None) -> None:
        arm = pricer.arm
        k, dof, n = arm.n_branches, arm.dof, n_waypoints
        self.size, self.n_waypoints, self.pricer = size, n_waypoints, pricer
        self.observations, self.checks = observations, checks
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
        self.lengths = np.full(size, n, dtype=np.int64)
        self.templates = np.zeros((size, n + 1, observations.size), dtype=np.float32)
        #: Per row: process continuity (``envs.process``): which moves lie inside a
        #: segment, the step limit, and the branch the arm stands in (−1: the start).
        self.inside = np.zeros((size, n), dtype=bool)
        self.limits = np.full(size, np.inf)
        self.branch = np.full(size, -1, dtype=np.int64)
        #: Per row and branch of its next waypoint: the move's path was checked (with
        #: ``observations.checked_moves`` the survey checks only some; ``stepping``).
        self.checked = np.ones((size, k), dtype=bool)
        self._configuration = np.ascontiguousarray(arm.branch_closed_form, dtype=np.int64)
        self._revolute = np.ascontiguousarray(arm.revolute_mask)
        #: Per row: the priced moves of its current state into its next waypoint (the
        #: value and flag blocks ``_price`` writes, row first so that a row's view is
        #: contiguous as the batch's arrays are: one compiled version of the stages
        #: serves both), and its observation.
        self.values = np.zeros((size, len(_VALUE_NAMES), k))
        self.flags = np.zeros((size, 3, k), dtype=bool)
        self.observation = np.zeros((size, observations.size), dtype=np.float32)
        #: Per row: its scene in ``checks`` and the token of the scene standing there now
        #: (the path memo's key: ``set_scene``).
        self.scenes = np.arange(size, dtype=np.int64) if scenes is None else np.asarray(
            scenes, dtype=np.int64)
        self.tokens = np.zeros(size, dtype=np.int64)
        self._memo = stepping.memo_arrays(dof)
        self._copies = stepping.copy_memo_arrays(dof)
        self._bind()

    def _bind(self) -> None:
        """(Re)build the compiled stages' view of the arrays."""
        pricer, builder = self.pricer, self.observations
        cost, layout = pricer.cost, builder.layout
        #: ``stepping``'s numbers (weights, penalties, grid, layout counts, turn copies).
        self._numbers = numbers = np.array([
            cost.travel_weight, cost.time_weight, pricer.collision_penalty,
            pricer.invalid_penalty, float(pricer.terminate_on_collision),
            pricer.max_transition_cost, pricer.travel_scale, pricer.checker.resolution,
            builder.onward_moves, builder.checked_moves or 0,
            float(bool(pricer.arm.turn_windows))])
        onward = layout.get("slot0/free_travel_out", (-1, -1))
        ahead = layout.get("slot0/free_travel_onward", (-1, -1))
        slices = np.array([*layout["q"], *layout["slot0/travel"],
                           *layout["slot0/path_collision"], *onward, *ahead], dtype=np.int64)
        self._episodes = stepping.make_episodes(
            self.q, self.index, self.collided, self.invalid, self.candidates, self.valid,
            self.endpoint, self.free_start, self.lengths, self.templates, self.values,
            self.flags, self.observation, cost.weights, cost.speeds, numbers, slices,
            builder._centre, builder._half_range, pricer.checker.lever, self.scenes,
            self.tokens, *self._memo, self.inside, self.limits, self._configuration,
            self._revolute, self.branch, self.checked, *self._copies)

    #: The per-row arrays (a view of one row shares them).
    _ROW_ARRAYS = ("q", "index", "collided", "invalid", "candidates", "valid", "endpoint",
                   "start", "free_start", "lengths", "templates", "observation", "tokens",
                   "inside", "limits", "branch", "checked", "values", "flags")

    def view(self, row: int, checks: CompiledFilter) -> EpisodeBatch:
        """A batch of one whose arrays are row ``row`` of this batch's: what either does to
        the row, the other sees (a vector env's sub-env runs its episode in its row);
        ``checks``: the sub-env's own filter (its scene in it is 0)."""
        one = object.__new__(EpisodeBatch)
        one.size, one.n_waypoints, one.pricer = 1, self.n_waypoints, self.pricer
        one.observations, one.checks = self.observations, checks
        for name in self._ROW_ARRAYS:
            setattr(one, name, getattr(self, name)[row : row + 1])
        one.scenes, one._memo, one._copies = np.zeros(1, dtype=np.int64), self._memo, self._copies
        one._configuration, one._revolute = self._configuration, self._revolute
        one._bind()
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
        self.inside[row], self.limits[row] = ladder.inside, ladder.limit
        self.branch[row] = -1
        self.index[row] = 0
        self.collided[row] = self.invalid[row] = False

    def set_scene(self, row: int, token: int) -> None:
        """A new scene stands in row ``row``'s env (a clutter laid): path verdicts
        remembered for the old one no longer apply (``token``: a number no other scene
        of this process has had)."""
        self.tokens[row] = token

    def survey(self, rows: np.ndarray) -> None:
        """Price the moves of ``rows`` (int array) from their current state and assemble
        their observations (``self.observation[rows]``): one compiled call."""
        stepping.survey(self._episodes, self.checks._bound, rows)

    def advance(self, rows: np.ndarray, actions: np.ndarray) -> Steps:
        """Rows ``rows`` move to branch ``actions`` (ints in [0, K), checked by the caller)
        of their next waypoint, paying what :meth:`survey` priced."""
        count = len(rows)
        values = np.empty((len(_VALUE_NAMES), count))
        flags = np.empty((3, count), dtype=bool)
        success = np.empty(count, dtype=bool)
        waypoint = self.index[rows]
        stepping.advance(self._episodes, self.checks._bound, rows, actions, values, flags,
                         success)
        terms = {name: values[3 + i] for i, name in enumerate(REWARD_TERMS)}
        return Steps(waypoint=waypoint, branch=actions, reward=values[0], travel=values[1],
                     time=values[2], terms=terms, collision=flags[1], invalid=flags[2],
                     terminated=flags[0], success=success)

    def masks(self, rows: np.ndarray) -> np.ndarray:
        """(len(rows), K) bool: the valid branches of each row's next waypoint (with
        process continuity: that do not reconfigure the arm inside a segment); every
        branch once its episode is over (any action then, as the env allows)."""
        out = np.empty((len(rows), self.valid.shape[2]), dtype=bool)
        stepping.masks(self._episodes, np.ascontiguousarray(rows, dtype=np.int64), out)
        return out


#: Rows of ``EpisodeBatch.values``: as ``envs.moves._price`` writes them.
_VALUE_NAMES = ("reward", "travel", "time", *REWARD_TERMS)
