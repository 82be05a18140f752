"""Pricing of moves: IK candidates, collision verdicts and reward terms, in one place.

The env, its ``edge_rewards``, the DP planners and the rule baselines all price a move
through this module, so a planner's return is exactly what ``step`` pays and no baseline
reads env internals.

:class:`MovePricer` belongs to one env (its arm, collision checker, cost and penalties)
and owns the caches. A cache is cleared when it would grow past its bound (between calls,
never losing the call's own results):

==================== ============ ========================================================
cache                bound         key → value
==================== ============ ========================================================
poses                50,000        waypoint pose → IK candidates, validity, endpoint hits
ladders              32 MB         a task's poses and segments → its ladder's candidates,
                                   validity, endpoint hits and continuity
configurations       200,000       configuration → collides (the generators' predicate)
paths                200,000       (q0, q1) → the linear path collides
templates            64 MB         a task's candidates, validity and endpoint hits → the
                                   observation templates (``envs.observations``); kept
                                   from a task's second sighting (hashes of up to 100,000
                                   tasks remembered), so random tasks store nothing
==================== ============ ========================================================

A task with a finite pose set (the milling cell's tool changes) solves and checks each
pose and each move once, and assembles its observation templates once; random tasks
mostly miss, and a miss costs one batched call.

:class:`TaskMoves` is one task's ladder: the candidates of every waypoint and the price of
every move into it, by :meth:`TaskMoves.terms`, the one function that prices a move.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import cast, overload

import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.costs import TransitionCost
from ikbranch_gym.envs.jit import njit
from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.compiled import writable
from ikbranch_gym.envs.kinematics.singularities import singularity_margins
from ikbranch_gym.envs.models import CollisionChecker
from ikbranch_gym.envs.process import UNKNOWN, Continuity, continuity, move_blocked
from ikbranch_gym.envs.tasks import Task

#: Cache bounds (entries), see the module docstring.
POSE_CACHE_SIZE = 50_000
CONFIGURATION_CACHE_SIZE = 200_000
PATH_CACHE_SIZE = 200_000
#: Bound of the observation-template cache, in bytes (its entries are large: N + 1
#: observations a task), and of the tasks it remembers having seen once.
TEMPLATE_CACHE_BYTES = 64 * 2**20
TEMPLATE_SIGHTINGS = 100_000
#: Bound of the ladder cache, in bytes (a task's arrays and their fingerprint).
LADDER_CACHE_BYTES = 32 * 2**20

#: The reward terms of a move, in the order they are summed (``info`` reports each).
REWARD_TERMS = ("reward_travel", "reward_time", "reward_collision", "reward_invalid",
                "reward_unfinished")


@dataclass
class _Cache:
    """A dict cleared when it would grow past ``bound``."""

    bound: int
    entries: dict = field(default_factory=dict)

    def make_room(self, count: int) -> None:
        if len(self.entries) + count > self.bound:
            self.entries.clear()

    def __len__(self) -> int:
        return len(self.entries)


@dataclass(frozen=True)
class _Ladder:
    """What a task's ladder holds beyond the task: its arrays (shared by every ladder of
    the task, written by none), its continuity (None without) and its fingerprint (the
    arrays' bytes: with the continuity, what the observation templates are keyed by)."""

    candidates: np.ndarray
    valid: np.ndarray
    endpoint: np.ndarray
    continuity: Continuity | None
    fingerprint: tuple[bytes, bytes, bytes] | None

    @property
    def nbytes(self) -> int:
        return 2 * (self.candidates.nbytes + self.valid.nbytes + self.endpoint.nbytes)


class MovePricer:
    """Prices the moves of one arm in one scene with one cost and penalty setting.

    ``checker`` decides collisions; ``cost`` prices travel and time; the penalties and
    ``terminate_on_collision`` are the env's; ``max_joint_step`` (rad, ``"auto"`` or None:
    off) keeps process continuity (``envs/process.py``) in the ladders it makes;
    ``singularity_margin`` (rad: wrist and elbow) and ``shoulder_margin`` (m) leave out of
    them every branch that close to a singular configuration
    (``envs.kinematics.singularities``; None: no margin). Shared by
    every :class:`TaskMoves` it makes, so caches survive from task to task.
    """

    def __init__(
        self,
        arm: Arm,
        checker: CollisionChecker,
        cost: TransitionCost,
        *,
        collision_penalty: float,
        invalid_penalty: float,
        terminate_on_collision: bool,
        max_joint_step: float | str | None = None,
        singularity_margin: float | None = None,
        shoulder_margin: float | None = None,
    ) -> None:
        self.arm, self.checker, self.cost = arm, checker, cost
        self.max_joint_step = max_joint_step
        self.singularity_margin, self.shoulder_margin = singularity_margin, shoulder_margin
        self.collision_penalty = float(collision_penalty)
        self.invalid_penalty = float(invalid_penalty)
        self.terminate_on_collision = bool(terminate_on_collision)
        lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
        #: The largest travel of any move (between opposite joint limits): normalises the
        #: observation's travel.
        self.travel_scale = float(cost.travel(lower, upper))
        #: The dearest move any branch choice can cost (travel and time between opposite
        #: joint limits); an episode that ends early pays it for every waypoint it skips.
        self.max_transition_cost = float(
            cost.travel_weight * self.travel_scale + cost.time_weight * cost.time(lower, upper)
        )
        #: What :func:`_price` takes after the moves: weights, speeds, the reward weights
        #: and penalties.
        self.price_arguments = (cost.weights, cost.speeds, cost.travel_weight,
                                cost.time_weight, self.collision_penalty, self.invalid_penalty,
                                self.terminate_on_collision, self.max_transition_cost)
        self.poses = _Cache(POSE_CACHE_SIZE)
        self.configurations = _Cache(CONFIGURATION_CACHE_SIZE)
        self.paths = _Cache(PATH_CACHE_SIZE)
        #: (poses, segments) bytes of a task → its ladder's arrays (candidates,
        #: valid, endpoint_collision), continuity and fingerprint; cleared when it would
        #: grow past ``LADDER_CACHE_BYTES``.
        self.ladders: dict[tuple[bytes, bytes | None], _Ladder] = {}
        self._ladder_bytes = 0
        self.branch_configuration = np.ascontiguousarray(arm.branch_closed_form,
                                                         dtype=np.int64)
        self.revolute = arm.revolute_mask

    def clear_caches(self) -> None:
        """Forget every cached verdict (the scene changed: ``scene_seed=None``)."""
        for cache in (self.poses, self.configurations, self.paths):
            cache.entries.clear()
        self.ladders.clear()
        self._ladder_bytes = 0

    # ------------------------------------------------------------------ candidates
    def solve(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``candidates`` (N, K, dof), ``valid`` (N, K), ``endpoint_collision`` (N, K) of
        waypoint ``poses`` (N, 4, 4): one batched IK call and one batched configuration
        check for the poses not seen before (IK is row-wise exact, so a cached row is the
        row a fresh call would give)."""
        poses = np.ascontiguousarray(poses, dtype=np.float64)
        cache = self.poses.entries
        keys = [pose.tobytes() for pose in poses]
        rows = [cache.get(key) for key in keys]
        missing = list({keys[i]: i for i, row in enumerate(rows) if row is None}.values())
        if missing:
            candidates, valid = self.arm.ik(poses[missing])
            endpoint = self._endpoint_collision(candidates, valid)
            new = {
                keys[i]: (candidates[row], valid[row], endpoint[row])
                for row, i in enumerate(missing)
            }
            self.poses.make_room(len(new))
            cache.update(new)
            rows = [new[key] if row is None else row for key, row in zip(keys, rows, strict=True)]
        # Every row is a cache hit or was solved just now: none is None.
        solved = cast(list[tuple[np.ndarray, np.ndarray, np.ndarray]], rows)
        return (
            np.array([row[0] for row in solved]),
            np.array([row[1] for row in solved]),
            np.array([row[2] for row in solved]),
        )

    def _endpoint_collision(self, candidates: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """(M, K) bool: each valid candidate's configuration collides (``candidates`` (M, K,
        dof) of M poses), through this pricer's checker (:func:`endpoint_collision`)."""
        checker = self.checker
        return endpoint_collision(
            self.arm, candidates, valid,
            lambda rows, _: checker.rows_collide_proved(rows),
            lambda rows, _: checker.rows_collide(rows), np.zeros(len(valid), dtype=np.int64))

    def task(self, task: Task) -> TaskMoves:
        """The ladder of ``task``: its candidates solved, ready to price moves. With process
        continuity, branches from which their segment cannot be followed are invalid
        (their rows NaN); ``ValueError`` for a segment no branch sequence follows. A task
        whose poses and segments were met before (a finite pose set) takes the arrays of
        that ladder, which are the arrays solving it again would give."""
        key = (np.asarray(task.poses, dtype=np.float64).tobytes(),
               None if task.segments is None else
               np.asarray(task.segments, dtype=np.int64).tobytes())
        known = self.ladders.get(key)
        if known is None:
            known = self._ladder(task)
            if self._ladder_bytes + known.nbytes > LADDER_CACHE_BYTES:
                self.ladders.clear()
                self._ladder_bytes = 0
            self.ladders[key] = known
            self._ladder_bytes += known.nbytes
        return TaskMoves(self, task, known.candidates, known.valid, known.endpoint,
                         known.continuity, known.fingerprint)

    def solved(self, task: Task, candidates: np.ndarray, valid: np.ndarray,
               endpoint: np.ndarray) -> TaskMoves:
        """The ladder of ``task`` from its candidates, validity and endpoint hits solved
        elsewhere (a batch of resets solves every env's waypoints in one call): the
        singularity margins and process continuity applied as :meth:`task` applies them."""
        known = self._restricted(task, candidates, valid, endpoint, fingerprint=False)
        return TaskMoves(self, task, known.candidates, known.valid, known.endpoint,
                         known.continuity)

    def _ladder(self, task: Task) -> _Ladder:
        """The arrays of :meth:`task`'s ladder, solved. They are shared by the ladders of
        every task with these poses, and nothing writes to them (the kernels take them
        writable: numba would compile a read-only array's version apart)."""
        candidates, valid, endpoint = self.solve(task.poses)
        return self._restricted(task, candidates, valid, endpoint, fingerprint=True)

    def _restricted(self, task: Task, candidates: np.ndarray, valid: np.ndarray,
                    endpoint: np.ndarray, fingerprint: bool) -> _Ladder:
        """A ladder's arrays from the solved ones: branches inside the singularity margins
        left out, then, with process continuity, those from which their segment cannot be
        followed (their rows NaN); with ``fingerprint``, the arrays' bytes too."""
        if not valid.any(axis=-1).all():
            raise RuntimeError("task generator produced a waypoint without a valid branch")
        if self.singularity_margin is not None or self.shoulder_margin is not None:
            clear = self._clear_of_singularities(candidates, valid)
            candidates = np.where(clear[..., None], candidates, np.nan)
            valid, endpoint = clear, endpoint & clear
        kept = None
        if self.max_joint_step is not None:
            segments = (np.zeros(task.n_waypoints, dtype=np.int64) if task.segments is None
                        else task.segments)
            kept, valid = continuity(candidates, valid, segments, self.branch_configuration,
                                     self.revolute, self.max_joint_step)
            candidates = np.where(valid[..., None], candidates, np.nan)
            endpoint = endpoint & valid
        return _Ladder(candidates, valid, endpoint, kept,
                       (candidates.tobytes(), valid.tobytes(), endpoint.tobytes())
                       if fingerprint else None)

    def _clear_of_singularities(self, candidates: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """(N, K): valid branches outside the singularity margins; ``ValueError`` naming
        every waypoint left without one."""
        clear = valid & self._outside_margins(candidates)
        angle, shoulder = self.singularity_margin, self.shoulder_margin
        stuck = np.flatnonzero(~clear.any(axis=-1))
        if len(stuck):
            limits = ", ".join(part for part in (
                None if angle is None else f"wrist and elbow {np.degrees(angle):g}°",
                None if shoulder is None else f"shoulder {1000 * shoulder:g} mm") if part)
            raise ValueError(f"waypoints {stuck.tolist()}: every branch lies within the "
                             f"singularity margins ({limits})")
        return clear

    def _outside_margins(self, q: np.ndarray) -> np.ndarray:
        """(…,) True where configuration ``q[…]`` (…, dof) lies outside the singularity
        margins set (NaN rows: False)."""
        margins = singularity_margins(self.arm, q)
        clear = np.isfinite(q).all(axis=-1)
        if self.singularity_margin is not None:
            clear &= (margins.wrist >= self.singularity_margin) & (
                margins.elbow >= self.singularity_margin)
        if self.shoulder_margin is not None:
            clear &= margins.shoulder >= self.shoulder_margin
        return clear

    # ------------------------------------------------------------------ collisions
    def configurations_collide(self, q: np.ndarray) -> np.ndarray:
        """(M,) bool for configurations ``q`` (M, dof), through the cache."""
        q = _finite_rows(q, "configurations")
        keys = [row.tobytes() for row in q]
        return self._cached(self.configurations, keys,
                            lambda index: self.checker.rows_collide(q[index]))

    def paths_collide(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """(M,) bool: the linear path from ``q0`` ((dof,) or (M, dof)) to each of ``q1``
        (M, dof) collides, through the cache; the misses go through one checker call."""
        q1 = _finite_rows(q1, "path ends")
        if np.ndim(q0) == 1:
            q0 = _finite_rows(np.asarray(q0)[None], "path starts")
            prefix = q0.tobytes()
            keys = [prefix + row.tobytes() for row in q1]

            def compute(index: np.ndarray) -> np.ndarray:
                return self.checker.rows_paths_collide(q0, q1[index])
        else:
            q0 = _finite_rows(q0, "path starts")
            keys = [a.tobytes() + b.tobytes() for a, b in zip(q0, q1, strict=True)]

            def compute(index: np.ndarray) -> np.ndarray:
                return self.checker.rows_paths_collide(q0[index], q1[index])
        return self._cached(self.paths, keys, compute)

    @staticmethod
    def _cached(cache: _Cache, keys: list[bytes],
                compute: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        entries = cache.entries
        found = [entries.get(key) for key in keys]
        missing = [i for i, value in enumerate(found) if value is None]
        if missing:
            values = compute(np.array(missing)).tolist()
            cache.make_room(len(missing))  # ``found`` keeps this call's hits
            for i, value in zip(missing, values, strict=True):
                found[i] = entries[keys[i]] = value
        return np.array(found, dtype=bool)

    # ------------------------------------------------------- the generators' predicates
    def is_free(self, q: np.ndarray, need: int | None = None) -> np.ndarray:
        """(M,) True where configuration ``q[i]`` is collision-free. With ``need`` (the
        generators' sampling, ``envs.tasks.base.FreePredicate``) rows are checked in order
        until ``need`` free ones are found, and the rows after come back False unchecked
        (and uncached)."""
        if need is None:
            return ~self.configurations_collide(q)
        q = _finite_rows(q, "configurations")
        entries = self.configurations.entries
        keys = [row.tobytes() for row in q]
        free = np.zeros(len(q), dtype=bool)
        start = 0
        while start < len(q) and free.sum() < need:
            # Cached rows answer at once; a run of unknown ones goes to the checker.
            known = entries.get(keys[start])
            if known is not None:
                free[start] = not known
                start += 1
                continue
            stop = start
            while stop < len(q) and keys[stop] not in entries:
                stop += 1
            wanted = need - int(free.sum())
            found = self.checker.first_free_rows(q[start:stop], wanted)
            checked = stop - start if len(found) < wanted else int(found[-1]) + 1
            self.configurations.make_room(checked)
            block = np.zeros(stop - start, dtype=bool)
            block[found] = True
            for i in range(checked):
                entries[keys[start + i]] = not block[i]
            free[start : start + checked] = block[:checked]
            start += checked
        return free

    def is_workable(self, q: np.ndarray, need: int | None = None) -> np.ndarray:
        """(M,) True where configuration ``q[i]`` is collision-free and outside the
        singularity margins: what a generator may build its task on, since the ladder
        leaves every branch inside them out (a task drawn on such branches could leave a
        waypoint without one). Without margins, :meth:`is_free` itself; ``need`` as there,
        counted among the rows outside the margins."""
        if self.singularity_margin is None and self.shoulder_margin is None:
            return self.is_free(q, need)
        q = _finite_rows(q, "configurations")
        clear = self._outside_margins(q)
        workable = np.zeros(len(q), dtype=bool)
        workable[clear] = self.is_free(q[clear], need)
        return workable

    def is_path_free(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """(M,) True where the path ``q0[i]`` → ``q1[i]`` is collision-free (one call)."""
        return ~self.paths_collide(np.asarray(q0), np.asarray(q1))


#: ``decide(rows (M, dof), scenes (M,)) -> (collides (M,), proved (M,))``: configuration
#: verdicts, each in its scene, and whether a proof of the filter decided each (rather
#: than MuJoCo); ``recheck(rows, scenes) -> collides``: MuJoCo's own verdicts.
Decide = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
Recheck = Callable[[np.ndarray, np.ndarray], np.ndarray]


def endpoint_collision(arm: Arm, candidates: np.ndarray, valid: np.ndarray, decide: Decide,
                       recheck: Recheck, scenes: np.ndarray) -> np.ndarray:
    """(M, K) bool: each valid candidate's configuration collides (``candidates`` (M, K,
    dof) of M poses, pose m in scene ``scenes[m]``). The turn copies of one closed-form
    branch place every link alike (up to rounding far below the filter's tolerances), so
    one check of the first copy serves them all where a proof of the filter decided it;
    where MuJoCo decided, every copy is asked of MuJoCo itself."""
    endpoint = np.zeros(valid.shape, dtype=bool)
    rows, branches = np.nonzero(valid)
    if not len(rows):
        return endpoint
    if arm.turn_windows:
        group = rows * arm.n_closed_form + arm.branch_closed_form[branches]
        _, first, inverse = np.unique(group, return_index=True, return_inverse=True)
    else:  # no turn copies: every candidate its own
        first = inverse = np.arange(len(rows))
    representatives = np.ascontiguousarray(candidates[rows[first], branches[first]])
    _finite_rows(representatives, "configurations")
    hits, proved = decide(representatives, scenes[rows[first]])
    verdict = hits[inverse]
    again = ~proved[inverse]
    again[first] = False  # the representatives themselves: MuJoCo's own verdict
    if again.any():
        verdict[again] = recheck(
            np.ascontiguousarray(candidates[rows[again], branches[again]]), scenes[rows[again]])
    endpoint[rows, branches] = verdict
    return endpoint


#: Rows of the value block of :func:`_price`; the flag block holds terminal, collision,
#: invalid.
_VALUES = ("reward", "travel", "time", *REWARD_TERMS)
_FLAGS = ("terminal", "collision", "invalid")


@njit
def _price(origins: np.ndarray, candidates: np.ndarray, valid: np.ndarray,
           waypoints: np.ndarray, collision: np.ndarray, blocked: np.ndarray,
           free_start: np.ndarray, n: np.ndarray,
           weights: np.ndarray, speeds: np.ndarray, travel_weight: float, time_weight: float,
           collision_penalty: float, invalid_penalty: float, terminate: bool,
           max_cost: float, values: np.ndarray, flags: np.ndarray) -> None:
    """Every term of the moves from ``origins[w, r]`` to ``candidates[w, k]``, the
    candidates of waypoint ``waypoints[w]`` of a task of ``n[w]`` waypoints whose start is
    free when ``free_start[w]`` (see :meth:`TaskMoves.terms`): ``values``
    (len(_VALUES), W, R, K) and ``flags`` (3, W, R, K). A ``blocked`` (W, R, K) move (it
    reconfigures the arm inside a process segment) is priced as an invalid branch. Rows w
    may come from one task or, in a batch of episodes, each from its own. Travel
    Σ_j w_j|Δq_j| is summed in joint order, time is max_j |Δq_j|/v_j (NaN in, NaN out); the
    reward is the sum of its terms in ``REWARD_TERMS`` order."""
    count, rows, k = collision.shape
    dof = origins.shape[2]
    for w in range(count):
        waypoint = waypoints[w]
        length = n[w]
        still = free_start[w] and waypoint == 0
        for r in range(rows):
            for b in range(k):
                invalid = not valid[w, b] or blocked[w, r, b]
                travel = duration = 0.0
                if not still:
                    # An invalid branch stays where it is: no motion (NaN from no origin).
                    unknown = False
                    for j in range(dof):
                        start = origins[w, r, j]
                        step = abs((start if invalid else candidates[w, b, j]) - start)
                        travel += step * weights[j]
                        pace = step / speeds[j]
                        if pace != pace:
                            unknown = True
                        elif j == 0 or pace > duration:
                            duration = pace
                    if unknown:
                        duration = np.nan
                hit = collision[w, r, b] and not blocked[w, r, b]  # a move not made
                crashed = hit and terminate
                skipped = (length - waypoint if invalid
                           else (length - 1 - waypoint if crashed else 0))
                reward_travel = -travel_weight * travel
                reward_time = -time_weight * duration
                reward_collision = -collision_penalty if hit else 0.0
                reward_invalid = -invalid_penalty if invalid else 0.0
                reward_unfinished = float(-skipped) * max_cost if skipped > 0 else 0.0
                values[0, w, r, b] = (reward_travel + reward_time + reward_collision
                                      + reward_invalid + reward_unfinished)
                values[1, w, r, b], values[2, w, r, b] = travel, duration
                values[3, w, r, b], values[4, w, r, b] = reward_travel, reward_time
                values[5, w, r, b], values[6, w, r, b] = reward_collision, reward_invalid
                values[7, w, r, b] = reward_unfinished
                flags[0, w, r, b] = invalid or crashed or waypoint == length - 1
                flags[1, w, r, b], flags[2, w, r, b] = hit, invalid


@njit
def _block_moves(origins: np.ndarray, candidates: np.ndarray, inside: np.ndarray,
                 origin_config: np.ndarray, configuration: np.ndarray, limit: float,
                 revolute: np.ndarray, out: np.ndarray) -> None:
    """``out[w, r, k]`` |= the move from ``origins[w, r]`` (configuration
    ``origin_config[r]``) to ``candidates[w, k]`` (``configuration[k]``) reconfigures the
    arm, where ``inside[w]`` (``envs.process.move_blocked``)."""
    for w in range(origins.shape[0]):
        if not inside[w]:
            continue
        for r in range(origins.shape[1]):
            for k in range(candidates.shape[1]):
                if move_blocked(origins[w, r], origin_config[r], candidates[w, k],
                                configuration[k], limit, revolute):
                    out[w, r, k] = True


@njit(inline="always")
def _by_joint(ends: np.ndarray, out: np.ndarray) -> None:
    """``out[j, b]`` = ``ends[b, j]``: configurations (K, dof) laid out by joint (dof, K),
    for :func:`_travel_to_all`."""
    for j in range(out.shape[0]):
        for b in range(out.shape[1]):
            out[j, b] = ends[b, j]


@njit(inline="always")
def _travel_to_all(start: np.ndarray, across: np.ndarray, weights: np.ndarray,
                   out: np.ndarray) -> None:
    """``out[b]`` = Σ_j w_j|across[j, b] − start[j]| summed in joint order, as
    :func:`_price` sums a move's travel, for every b at once (``across``: the ends laid
    out by joint, :func:`_by_joint`; the loop over b is one the compiler vectorises)."""
    out[:] = 0.0
    for j in range(len(start)):
        origin, weight = start[j], weights[j]
        for b in range(len(out)):
            out[b] += abs(across[j, b] - origin) * weight


@njit
def _onward_travel(here: np.ndarray, there: np.ndarray, rows: np.ndarray, targets: np.ndarray,
                   weights: np.ndarray, out: np.ndarray) -> None:
    """``out[l, a, b]`` (L, K, K): per line l the travel from ``here[l, a]`` to
    ``there[l, b]`` where ``rows[l, a]`` and ``targets[l, b]``, summed as :func:`_price`
    sums it (Σ_j w_j|Δq_j| in joint order), +inf elsewhere in those rows; ``rows[l, a]``
    is cleared where no target is left. Rows l, a where ``rows[l, a]`` is False are not
    written: nothing reads them (on a K = 256 arm they are most of the array, which
    filling cost more than the rest of a survey's bookkeeping). A row's travel is summed
    for every b at once (:func:`_travel_to_all`)."""
    dof, k = here.shape[2], there.shape[1]
    across = np.empty((dof, k))
    travel = np.empty(k)
    for line in range(here.shape[0]):
        loaded = False
        for a in range(here.shape[1]):
            if not rows[line, a]:
                continue
            if not loaded:
                _by_joint(there[line], across)
                loaded = True
            _travel_to_all(here[line, a], across, weights, travel)
            reached = False
            for b in range(k):
                if targets[line, b]:
                    out[line, a, b] = travel[b]
                    reached = reached or travel[b] < np.inf
                else:
                    out[line, a, b] = np.inf
            rows[line, a] = reached


@njit
def _next_targets(lines: np.ndarray, rows: np.ndarray, travel: np.ndarray, last: np.ndarray,
                  columns: np.ndarray) -> None:
    """Per asking (``lines[i]``, ``rows[i]``): its next target, the cheapest one after
    ``last`` in the order (travel, target index) — the order a stable sort of the row
    gives, found by one scan instead of sorting every row (a K = 256 arm's rows are mostly
    decided by their first target). ``columns[i]`` −1 where none is left."""
    k = travel.shape[2]
    for i in range(len(rows)):
        line, row = lines[i], rows[i]
        after = last[line, row]
        floor = travel[line, row, after] if after >= 0 else -np.inf
        best, pick = np.inf, -1
        for b in range(k):
            value = travel[line, row, b]
            if not value < np.inf:
                continue
            if value < floor or (value == floor and b <= after):
                continue  # tried already
            if value < best:
                best, pick = value, b
        columns[i] = pick


@njit
def _take_or_try_next(lines: np.ndarray, rows: np.ndarray, columns: np.ndarray,
                      hits: np.ndarray, travel: np.ndarray, last: np.ndarray, out: np.ndarray,
                      pending: np.ndarray) -> None:
    """One round of :func:`least_free_travel`: row ``rows[i]`` of line ``lines[i]`` whose
    path to ``columns[i]`` is free takes that travel; the others remember it as tried and
    move on to their next cheapest target in the next round."""
    for i in range(len(rows)):
        line, row = lines[i], rows[i]
        if not hits[i]:
            out[line, row] = travel[line, row, columns[i]]
            pending[line, row] = False
        else:
            last[line, row] = columns[i]


#: ``paths_collide(lines (M,), starts (M, dof), ends (M, dof)) -> (M,) bool``: the path
#: verdicts of M moves, each of one line of a batch (a task, an episode, a sub-env).
LinePaths = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def least_free_travel(here: np.ndarray, there: np.ndarray, branches: np.ndarray,
                      targets: np.ndarray, weights: np.ndarray,
                      paths_collide: LinePaths, blocked: np.ndarray | None = None) -> np.ndarray:
    """(L, K) per line l and branch a where ``branches[l, a]``: the least travel from
    ``here[l, a]`` (L, K, dof) to a ``there[l, b]`` with ``targets[l, b]`` along a
    collision-free path, +inf where there is none and where ``branches`` is False.

    Paths are checked cheapest first (ties: the lower target index), one
    ``paths_collide`` call per round for every branch of every line still undecided,
    until each finds a free one: usually one or two rounds. Targets are the free branches
    of the next waypoint (valid, their configuration collision-free: a path ends in its
    target). ``blocked`` (L, K, K): moves that are no moves (they would reconfigure the
    arm inside a process segment)."""
    lines_count, k = branches.shape
    out = np.full((lines_count, k), np.inf)
    travel = np.empty((lines_count, k, k))
    pending = np.array(branches, dtype=np.bool_)
    _onward_travel(here, there, pending, targets, weights, travel)
    if blocked is not None:
        travel[blocked & pending[..., None]] = np.inf
        pending[pending] = np.isfinite(travel[pending]).any(axis=-1)
    last = np.full((lines_count, k), -1, dtype=np.int64)
    while pending.any():
        lines, rows = np.nonzero(pending)
        columns = np.empty(len(lines), dtype=np.int64)
        _next_targets(lines, rows, travel, last, columns)
        done = columns < 0
        if done.any():  # no target left: +inf
            pending[lines[done], rows[done]] = False
            lines, rows, columns = lines[~done], rows[~done], columns[~done]
            if not len(lines):
                break
        hits = paths_collide(lines, here[lines, rows], there[lines, columns])
        _take_or_try_next(lines, rows, columns, hits, travel, last, out, pending)
    return out


def _finite_rows(q: ArrayLike, what: str) -> np.ndarray:
    """``q`` as C-contiguous float64 rows (M, dof), ``ValueError`` if any value is NaN/inf."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    if q.ndim != 2 or not np.isfinite(q).all():
        raise ValueError(f"{what} must be finite rows (M, dof), got shape {q.shape}")
    return q


class TaskMoves:
    """One task's ladder: waypoint i's candidates ``candidates[i]`` (K, dof) (NaN where
    invalid), ``valid[i]``, ``endpoint_collision[i]``, and the price of every move.

    Moves into waypoint 0 start at ``task.start`` (one origin row); moves into waypoint
    i > 0 start at the K candidates of waypoint i − 1 (rows of invalid ones are NaN).

    With process continuity (``continuity``, ``envs/process.py``) a move inside a segment
    that reconfigures the arm is outside the action mask and priced as an invalid branch
    (no motion, ``invalid_penalty``, the episode ends). An origin block of K rows is the
    previous waypoint's candidates (row r: branch r, its configuration known); a single row
    is any configuration (its configuration unknown: only the step limit applies).
    """

    def __init__(self, pricer: MovePricer, task: Task, candidates: np.ndarray,
                 valid: np.ndarray, endpoint_collision: np.ndarray,
                 continuity: Continuity | None = None,
                 fingerprint: tuple[bytes, bytes, bytes] | None = None) -> None:
        self.pricer, self.task = pricer, task
        self.candidates, self.valid = candidates, valid
        self.endpoint_collision = endpoint_collision
        self.n_waypoints = task.n_waypoints
        self._waypoints = np.arange(self.n_waypoints)
        self.continuity = continuity
        #: Per waypoint: the move into it lies inside a process segment (all False
        #: without continuity); the step limit (rad; +inf without).
        self.inside = (np.zeros(self.n_waypoints, dtype=bool) if continuity is None
                       else continuity.inside)
        self.limit = np.inf if continuity is None else continuity.limit
        self.configuration, self.revolute = pricer.branch_configuration, pricer.revolute
        self._fingerprint = fingerprint

    @property
    def fingerprint(self) -> tuple[bytes, bytes, bytes]:
        """The bytes of ``candidates``, ``valid`` and ``endpoint_collision``: with
        ``inside`` and ``limit``, what the observation templates depend on (their cache's
        key)."""
        if self._fingerprint is None:
            self._fingerprint = (self.candidates.tobytes(), self.valid.tobytes(),
                                 self.endpoint_collision.tobytes())
        return self._fingerprint

    def origins(self, waypoint: int) -> tuple[np.ndarray, np.ndarray]:
        """Where the arm can stand before ``waypoint``: rows (R, dof) and which exist."""
        waypoint = int(self._check_waypoint(waypoint))
        if waypoint == 0:
            return np.asarray(self.task.start, dtype=np.float64)[None], np.ones(1, dtype=bool)
        return self.candidates[waypoint - 1], self.valid[waypoint - 1]

    def motion(self, origins: np.ndarray, waypoint: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """``travel`` and ``time`` (…, R, K) of the moves from ``origins`` (…, R, dof) to
        every branch of ``waypoint`` (an int, or an array of the leading shape …);
        invalid branches do not move, and at a free start (waypoint 0) nothing moves: the
        first step only picks the branch the arm already stands in."""
        values, _ = self._price(origins, waypoint, None)
        return values[1], values[2]

    def collisions(self, origins: np.ndarray, waypoint: int,
                   branches: np.ndarray | None = None) -> np.ndarray:
        """(R, K) bool: the move from each origin row (R, dof) to each branch of
        ``waypoint`` collides (its path; at a free start the branch's own configuration).
        Invalid branches, and pairs outside ``branches`` (R, K) bool when given, are
        False. The paths go through one (cached) checker call."""
        waypoint = self._check_waypoint(waypoint)
        valid = self.valid[waypoint]
        if len(origins) == 1 and branches is None:  # a step's moves: one row
            out = np.zeros((1, len(valid)), dtype=bool)
            if waypoint == 0 and self.task.free_start:
                out[0] = self.endpoint_collision[0] & valid
            elif valid.any():
                out[0, valid] = self.pricer.paths_collide(origins[0], self.candidates[waypoint][
                    valid])
            return out
        wanted = np.broadcast_to(valid, (len(origins), len(valid)))
        if branches is not None:
            wanted = wanted & branches
        out = np.zeros(wanted.shape, dtype=bool)
        if waypoint == 0 and self.task.free_start:
            out[wanted] = np.broadcast_to(self.endpoint_collision[0], wanted.shape)[wanted]
            return out
        rows, columns = np.nonzero(wanted)
        if len(rows) == 0:
            return out
        out[rows, columns] = self.pricer.paths_collide(origins[rows],
                                                       self.candidates[waypoint][columns])
        return out

    def terms(self, origins: np.ndarray, waypoint: ArrayLike,
              collision: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Every reward term (…, R, K) of the moves from ``origins`` (…, R, dof) into each
        branch of ``waypoint`` (an int, or an array of the leading shape …), as ``step``
        pays them, with ``reward`` their sum (in ``REWARD_TERMS`` order) and ``terminal``
        whether the move ends the episode; also ``travel`` (rad-equivalents), ``time``
        (s), ``collision`` and ``invalid``. ``collision`` (…, R, K) gives the collision
        verdicts (a planner's optimistic or known ones); by default they are checked (an
        int waypoint only). The one function that prices a move (:func:`_price`)."""
        if collision is None:  # an int waypoint only (above): collisions checks it
            collision = self.collisions(origins, cast(int, waypoint))
        values, flags = self._price(origins, waypoint, collision)
        terms = dict(zip(_VALUES, values, strict=True))
        terms.update(zip(_FLAGS, flags, strict=True))
        return terms

    def _price(self, origins: np.ndarray, waypoint: ArrayLike,
               collision: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """:func:`_price` on any leading shape: value and flag blocks (…, R, K) each."""
        waypoint = self._check_waypoint(waypoint)
        k, dof = self.valid.shape[1], self.candidates.shape[2]
        flat: slice | np.ndarray
        if isinstance(waypoint, int):  # one waypoint, origins (R, dof): views, no copies
            flat = slice(waypoint, waypoint + 1)
            origins = np.ascontiguousarray(origins, dtype=np.float64)[None]
            lead, count = (), 1
        else:
            waypoints = np.asarray(waypoint, dtype=np.int64)
            lead, flat = waypoints.shape, waypoints.reshape(-1)
            count = len(flat)
            origins = np.ascontiguousarray(
                np.broadcast_to(origins, (*lead, origins.shape[-2], dof)), dtype=np.float64
            ).reshape(count, -1, dof)
        shape = (count, origins.shape[1], k)
        if collision is None:
            collision = np.zeros(shape, dtype=np.bool_)
        elif (isinstance(collision, np.ndarray) and collision.dtype == np.bool_
              and collision.shape == shape[1:] and collision.flags.c_contiguous and not lead):
            collision = collision.reshape(shape)  # a step's own verdicts: no copy needed
        else:
            collision = np.ascontiguousarray(np.broadcast_to(collision, (*lead, *shape[1:])),
                                             dtype=np.bool_).reshape(shape)
        values = np.empty((len(_VALUES), *shape))
        flags = np.empty((len(_FLAGS), *shape), dtype=np.bool_)
        pricer = self.pricer
        waypoints = self._waypoints[flat]
        blocked = np.zeros(shape, dtype=np.bool_)
        # A contiguous view np.broadcast_to made is read-only.
        origins, collision = writable(origins), writable(collision)
        if self.continuity is not None:
            origin_config = (self.configuration if shape[1] == len(self.configuration)
                             else np.full(shape[1], UNKNOWN, dtype=np.int64))
            _block_moves(origins, self.candidates[flat], self.inside[waypoints],
                         writable(origin_config), writable(self.configuration), self.limit,
                         self.revolute, blocked)
        _price(origins, self.candidates[flat], self.valid[flat], waypoints, collision, blocked,
               np.full(count, self.task.free_start), np.full(count, self.n_waypoints),
               *pricer.price_arguments, values, flags)
        out = (*lead, *shape[1:])
        return values.reshape(len(_VALUES), *out), flags.reshape(len(_FLAGS), *out)

    def blocked(self, origins: np.ndarray, waypoint: int) -> np.ndarray:
        """(R, K) bool: the move from each origin row (R, dof; see the class docstring)
        to each branch of ``waypoint`` reconfigures the arm inside a process segment (all
        False without continuity)."""
        waypoint = int(self._check_waypoint(waypoint))
        origins = np.ascontiguousarray(origins, dtype=np.float64)
        out = np.zeros((1, len(origins), self.valid.shape[1]), dtype=np.bool_)
        if self.continuity is not None:
            origin_config = (self.configuration if len(origins) == len(self.configuration)
                             else np.full(len(origins), UNKNOWN, dtype=np.int64))
            _block_moves(writable(origins[None]), self.candidates[waypoint][None],
                         self.inside[waypoint : waypoint + 1], writable(origin_config),
                         writable(self.configuration), self.limit, self.revolute, out)
        return out[0]

    def edges(self, waypoint: int) -> tuple[np.ndarray, np.ndarray]:
        """``reward`` (R, K) and ``terminal`` (R, K) of every move into ``waypoint`` from
        every origin row, every path checked; rows of origins that do not exist are NaN
        and terminal (``IKBranchEnv.edge_rewards``)."""
        origins, usable = self.origins(waypoint)
        k = self.valid.shape[1]
        reward = np.full((len(origins), k), np.nan)
        terminal = np.ones((len(origins), k), dtype=bool)
        if usable.any():
            terms = self.terms(origins[usable], waypoint)
            reward[usable], terminal[usable] = terms["reward"], terms["terminal"]
        return reward, terminal

    def stacked_origins(self) -> tuple[np.ndarray, np.ndarray]:
        """Every waypoint's origin rows at once: (N, K, dof) and which exist (N, K); the
        start is row 0 of waypoint 0 (its other rows do not exist)."""
        n, k, dof = self.candidates.shape
        origins = np.full((n, k, dof), np.nan)
        usable = np.zeros((n, k), dtype=bool)
        origins[0, 0], usable[0, 0] = self.task.start, True
        origins[1:], usable[1:] = self.candidates[:-1], self.valid[:-1]
        return origins, usable

    def least_free_travel(self, waypoint: int, branches: np.ndarray) -> np.ndarray:
        """(K,) per branch k of ``waypoint`` where ``branches[k]``: the least travel from
        it to a branch of the next waypoint along a collision-free path (+inf where there
        is none, where ``branches`` is False, and at the task's last waypoint).

        Paths are checked cheapest first, one checker call per round for every branch
        still undecided, until each finds a free one: usually one or two rounds. Targets
        whose configuration collides are skipped unchecked (a path ends in its target)."""
        waypoint = int(self._check_waypoint(waypoint))
        if waypoint + 1 >= self.n_waypoints:
            return np.full(self.valid.shape[1], np.inf)
        targets = self.valid[waypoint + 1] & ~self.endpoint_collision[waypoint + 1]
        blocked = (self.blocked(self.candidates[waypoint], waypoint + 1)[None]
                   if self.continuity is not None else None)
        return least_free_travel(
            self.candidates[waypoint][None], self.candidates[waypoint + 1][None],
            (branches & self.valid[waypoint])[None], targets[None], self.pricer.cost.weights,
            lambda lines, starts, ends: self.pricer.paths_collide(starts, ends), blocked)[0]

    def travel_from(self, q: np.ndarray, waypoint: int) -> np.ndarray:
        """(K,) travel from configuration ``q`` to each branch of ``waypoint`` (NaN for
        invalid branches; 0 at a free start): what the paper's rule compares."""
        travel, _ = self.motion(np.asarray(q, dtype=np.float64)[None], waypoint)
        return np.where(self.valid[waypoint], travel[0], np.nan)

    @overload
    def _check_waypoint(self, waypoint: int | np.integer) -> int: ...
    @overload
    def _check_waypoint(self, waypoint: ArrayLike) -> int | np.ndarray: ...
    def _check_waypoint(self, waypoint: ArrayLike) -> int | np.ndarray:
        """``waypoint`` as an int (from any integer) or an integer array, ``ValueError``
        outside [0, N)."""
        if isinstance(waypoint, int | np.integer):
            if not 0 <= waypoint < self.n_waypoints:
                raise ValueError(f"waypoint must lie in [0, {self.n_waypoints})")
            return int(waypoint)
        values = np.asarray(waypoint)
        if values.dtype.kind not in "iu" or (values.size and not (
            0 <= values.min() and values.max() < self.n_waypoints
        )):
            raise ValueError(f"waypoint must lie in [0, {self.n_waypoints})")
        return values
