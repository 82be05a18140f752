"""The ``random`` task's chain, compiled: the fast path of ``envs.tasks.random_reachable``.

``random_reachable`` draws a chain of collision-free configurations whose straight paths
are collision-free too, asking the env's predicates row by row from Python (tens of
calls a task, each a few µs of Python around the collision kernel). :func:`random_chain`
runs the very same algorithm in one compiled call: the same draws from the env's
``np_random`` (numba consumes a NumPy ``Generator`` exactly as NumPy does: ``uniform``
element by element in row-major order is ``uniform`` with array bounds), the same
collision verdicts (the compiled filter's, which are MuJoCo's), the same redraws and
backtracking, so it returns the same chain and leaves the generator in the same state
(tested on every random-task id). The env takes it where its checker is compiled.
"""

from __future__ import annotations

import numpy as np

from ikbranch_gym.envs.jit import njit
from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.models.filter import CompiledFilter
from ikbranch_gym.envs.models.filter.kernels import bound_configurations, bound_paths, path_steps
from ikbranch_gym.envs.tasks import Task
from ikbranch_gym.envs.tasks.base import SAMPLE_ROUNDS
from ikbranch_gym.envs.tasks.random_reachable import MAX_DRAWS, REDRAWS_BEFORE_BACKTRACK

#: :func:`_chain` status codes.
DONE, TOO_FEW_FREE, TOO_MANY_DRAWS = 0, 1, 2
#: The flags the kernels take, as run-time booleans: every caller then shares one
#: compiled version of them (a literal ``True`` would be typed, and compiled, apart).
_FLAGS = np.array([False, True])
#: Counts and offsets as run-time ints, for the same reason: numba compiles a kernel called
#: with a literal ``1`` or ``0`` apart from the same kernel called with a variable.
_COUNTS = np.array([0, 1])


def random_chain(arm: Arm, rng: np.random.Generator, n_waypoints: int,
                 checks: CompiledFilter, lever: np.ndarray, resolution: float) -> Task:
    """``random_reachable(arm, rng, n_waypoints, …)`` with the predicates of ``checks``
    (the env's filter; ``lever`` and ``resolution`` its checker's path grid)."""
    chain = random_chain_configurations(arm, rng, n_waypoints, checks, lever, resolution)
    return Task(start=chain[0], poses=arm.fk(chain[1:]))


def random_chain_configurations(arm: Arm, rng: np.random.Generator, n_waypoints: int,
                                checks: CompiledFilter, lever: np.ndarray,
                                resolution: float) -> np.ndarray:
    """The chain of :func:`random_chain`, (n_waypoints + 1, dof): its start and the
    configurations whose poses are the waypoints (a batch of envs takes their poses in
    one ``arm.fk`` call)."""
    lower, upper = arm.joint_limits[:, 0].copy(), arm.joint_limits[:, 1].copy()
    chain = np.empty((n_waypoints + 1, arm.dof))
    status, have, count = _chain(rng, lower, upper, n_waypoints, checks._bound, lever,
                                 float(resolution), chain, SAMPLE_ROUNDS)
    if status == TOO_FEW_FREE:
        raise RuntimeError(
            f"{arm.name}: found only {have} of {count} collision-free configurations in "
            f"{SAMPLE_ROUNDS} rounds; the scene leaves too little free space")
    if status == TOO_MANY_DRAWS:
        raise RuntimeError(
            f"{arm.name}: no chain of collision-free paths after {MAX_DRAWS} draws; "
            "the scene leaves too little free space")
    return chain


@njit
def _free_rows(rng, lower, upper, bound, count, out, at, rounds):
    """``sample_free_configurations``: ``count`` collision-free rows drawn uniformly
    inside the limits, written to ``out[at : at + count]``. Returns (status, rows had)."""
    have = 0
    dof = len(lower)
    for _ in range(rounds):
        wanted = count - have
        rows = max(2 * wanted, 8)
        draw = np.empty((rows, dof))
        for i in range(rows):
            for j in range(dof):
                draw[i, j] = rng.uniform(lower[j], upper[j])
        verdict, how = np.empty(rows, dtype=np.int64), np.empty(rows, dtype=np.int8)
        bound_configurations(bound, np.zeros(1, dtype=np.int64), draw, wanted, _FLAGS[1],
                             verdict, how)
        for i in range(rows):
            if verdict[i] == 0 and have < count:
                out[at + have] = draw[i]
                have += 1
        if have >= count:
            return DONE, have
    return TOO_FEW_FREE, have


@njit
def _links_free(bound, chain, links, count, lever, resolution, verdicts):
    """Check the paths chain[i − 1] → chain[i] of ``links[:count]`` in one call:
    ``verdicts[i]`` 1 free, 2 collides."""
    dof = chain.shape[1]
    starts, ends = np.empty((count, dof)), np.empty((count, dof))
    for m in range(count):
        starts[m], ends[m] = chain[links[m] - 1], chain[links[m]]
    steps = np.empty(count, dtype=np.int64)
    path_steps(starts, ends, lever, resolution, steps)
    out = np.empty(count, dtype=np.int64)
    bound_paths(bound, np.zeros(1, dtype=np.int64), starts, ends, steps, _FLAGS[0], out)
    for m in range(count):
        verdicts[links[m]] = 2 if out[m] >= 0 else 1


@njit
def _chain(rng, lower, upper, n, bound, lever, resolution, chain, rounds):
    """``random_reachable``'s walk (its docstring) into ``chain`` (n + 1, dof). Returns
    (status, rows had, rows wanted) of the last sampling (for the error message)."""
    status, have = _free_rows(rng, lower, upper, bound, n + 1, chain, _COUNTS[0], rounds)
    if status != DONE:
        return status, have, n + 1
    verdicts = np.zeros(n + 2, dtype=np.int64)  # link i: 0 unknown, 1 free, 2 collides
    links = np.empty(n + 1, dtype=np.int64)
    index, tries, draws = 1, 0, 0
    while index <= n:
        if verdicts[index] == 0:
            # The link the walk stands at and every unchecked one after the next, in one
            # call, as the generator asks them.
            links[0] = index
            count = _COUNTS[1]
            for i in range(index + 2, n + 1):
                if verdicts[i] == 0:
                    links[count] = i
                    count += 1
            _links_free(bound, chain, links, count, lever, resolution, verdicts)
        if verdicts[index] == 1:
            index, tries = index + 1, 0
            continue
        draws += 1
        if draws > MAX_DRAWS:
            return TOO_MANY_DRAWS, 0, 0
        tries += 1
        if tries >= REDRAWS_BEFORE_BACKTRACK:
            tries = 0
            if index > 1:
                index -= 1  # redraw the configuration we came from (checked again below)
            else:
                status, have = _free_rows(rng, lower, upper, bound, _COUNTS[1], chain, _COUNTS[0],
                                          rounds)
                if status != DONE:
                    return status, have, 1
                verdicts[1] = 0
                continue
        status, have = _free_rows(rng, lower, upper, bound, _COUNTS[1], chain, index, rounds)
        if status != DONE:
            return status, have, 1
        verdicts[index] = 0
        verdicts[index + 1] = 0
    return DONE, n + 1, n + 1
