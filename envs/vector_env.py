"""The natively batched vector env (see :class:`IKBranchVectorEnv`)."""

from __future__ import annotations

import itertools
import numbers
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ikbranch_gym.envs.episodes import EpisodeBatch, Steps
from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.models.filter import FilterStack
from ikbranch_gym.envs.resets import RESET_OPTIONS, begin_episodes


class IKBranchVectorEnv(VectorEnv):
    """``num_envs`` copies of :class:`~envs.ik_branch_env.IKBranchEnv` advanced together.

    ``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point")`` makes one
    for every registered id (``autoreset_mode="same_step"`` and any of the env's keyword
    arguments may be added). Sub-env i of a vector env reset with ``seed=s`` is the single
    env reset with ``seed=s + i``, bit for bit: the same observations, rewards,
    terminations and infos, through every autoreset (tested on every id against
    Gymnasium's ``SyncVectorEnv`` of single envs).

    ## How it runs
    Every sub-env keeps its own scene (clutter), random generator, task generator and
    caches, and runs its episode in one row of a shared :class:`~envs.episodes.EpisodeBatch`.
    A step advances all rows at once: the chosen moves are paid from what was priced
    before, then the new states are surveyed together — every path of every sub-env in one
    call of the compiled collision filter (its scenes stacked, :class:`FilterStack`),
    every move priced, the onward free travel and the observations in the same compiled
    call (``envs.stepping``), with a memo of the paths already checked (a finite pose
    set's moves recur from episode to episode). Only a reset's task drawing runs per
    sub-env.

    ## Threads
    ``threads=T`` (≥ 2) splits the sub-envs into T contiguous groups, each with its own
    batch, stacked filter and path memo, and steps the groups in T threads of this
    process: the compiled stages release Python's lock, so one group's kernels run
    while another's Python (a reset's task drawing) does. Every answer is the same as
    with one thread, bit for bit; what it buys depends on how much of a step is compiled
    (docs/training.md, "Threads of the vector env": with 16 sub-envs on two cores, two
    threads ran UR5e-v4 1.32–1.57× as fast with random actions, and the ids whose steps
    are mostly Python about as fast as one thread or slower).

    ## Spaces
    ``single_observation_space`` and ``single_action_space`` are the env's (``Box`` and
    ``Discrete(K)``); ``observation_space`` (N, size) and ``action_space``
    ``MultiDiscrete([K] * N)``.

    ## Masks
    ``info["action_mask"]`` (N, K) bool at every reset and step (the valid branches of each
    sub-env's next waypoint; all branches once an episode is over), and
    ``action_masks()``, the same array: a masked learner needs no round trip. An action
    outside ``[0, K)`` is refused with the sub-env named; an action outside its mask is
    the env's invalid branch (``invalid_penalty``, the episode ends), or refused with
    ``enforce_masks=True``.

    ## Autoreset
    As Gymnasium 1.x defines it (``metadata["autoreset_mode"]``): ``"next_step"`` (the
    default) resets a sub-env on the step after its episode ended, ignoring that step's
    action (reward 0, not terminated, the reset's info); ``"same_step"`` resets it within
    the step that ended it, returning the new episode's first observation and the reset's
    info, with the last observation and step info in ``info["final_obs"]`` and
    ``info["final_info"]``; ``"disabled"`` leaves it to ``reset(options={"reset_mask":
    mask})``. The first reset resets every sub-env, and so must the reset after a step or
    reset that raised (some sub-envs may have moved on before it failed): until then
    ``step`` refuses. Infos are batched as ``SyncVectorEnv`` batches them (an array per key, and
    ``info["_key"]`` marking the sub-envs that reported it).

    ## Arguments
    ``num_envs`` (≥ 1), ``autoreset_mode`` (an ``AutoresetMode``, its value or its name:
    ``"next_step"``, ``"same_step"``, ``"disabled"``), ``enforce_masks`` (default False),
    ``threads`` (1 to ``num_envs``, default 1), and every argument of ``IKBranchEnv`` (its
    docstring), the same for all sub-envs.
    """

    # Gymnasium's VectorEnv declares metadata a plain attribute (no ClassVar), as here.
    metadata: dict[str, Any] = {  # noqa: RUF012
        **IKBranchEnv.metadata, "autoreset_mode": AutoresetMode.NEXT_STEP,
    }
    envs: list[IKBranchEnv]
    autoreset_mode: AutoresetMode
    enforce_masks: bool
    n_branches: int
    threads: int
    _groups: list[_Group]
    _pool: ThreadPoolExecutor | None
    _rows: np.ndarray
    _ended: np.ndarray
    _started: bool

    def __init__(self, num_envs: int = 1, autoreset_mode: str | AutoresetMode =
                 AutoresetMode.NEXT_STEP, enforce_masks: bool = False, threads: int = 1,
                 **kwargs: Any) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, numbers.Integral) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if (isinstance(threads, bool) or not isinstance(threads, numbers.Integral)
                or not 1 <= threads <= num_envs):
            raise ValueError(f"threads must be an integer from 1 to num_envs ({num_envs}), "
                             f"got {threads!r}")
        mode = _autoreset_mode(autoreset_mode)
        self.num_envs, self.threads = int(num_envs), int(threads)
        self.autoreset_mode, self.enforce_masks = mode, bool(enforce_masks)
        #: The sub-envs (``IKBranchEnv``): their scenes, generators, ladders, renderers.
        self.envs = [IKBranchEnv(**kwargs) for _ in range(self.num_envs)]
        first = self.envs[0]
        self.metadata = {**type(self).metadata, "autoreset_mode": mode}
        self.render_mode = first.render_mode
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(first.observation_space, self.num_envs)
        self.action_space = batch_space(first.action_space, self.num_envs)
        self.observation_layout = first.observation_layout
        self.n_branches = first.arm.n_branches
        # Groups of nearly equal size, the larger first.
        size, more = divmod(self.num_envs, self.threads)
        starts = np.cumsum([0] + [size + (group < more) for group in range(self.threads)])
        self._groups = [_Group(self.envs[start:stop], int(start), self.threads == 1)
                        for start, stop in itertools.pairwise(starts.tolist())]
        self._pool = (ThreadPoolExecutor(self.threads - 1, thread_name_prefix="ikbranch")
                      if self.threads > 1 else None)
        self._rows = np.arange(self.num_envs)
        self._ended = np.zeros(self.num_envs, dtype=bool)
        self._started = False

    # ---------------------------------------------------------------------------- API
    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every sub-env (``seed=s``: sub-env i with ``s + i``; a list: one seed
        each), or with ``options={"reset_mask": mask}`` only those where ``mask`` (N,)
        bool is True (the others keep their state). ``options`` may also hold
        ``scene_seed`` and ``task_seed``, N entries each (an int, or None: drawn as
        usual), sub-env i reset as the single env with ``options={key: entries[i]}``."""
        seeds = self._seeds(seed)
        if isinstance(seed, numbers.Integral):  # the vector env's own generator, as Gymnasium's
            super().reset(seed=int(seed))
        options = dict(options or {})
        rows = self._rows
        if "reset_mask" in options:
            rows = np.flatnonzero(self._reset_mask(options.pop("reset_mask")))
            if not self._started and len(rows) < self.num_envs:
                raise ValueError("reset_mask: every sub-env must be reset first (the first "
                                 "reset, and the one after a failed step, reset them all)")
        chosen = self._reset_options(options)
        begun = self._run(lambda group, rows: group.reset(
            rows, [seeds[group.start + i] for i in rows],
            [chosen[group.start + i] for i in rows]), rows)
        infos = _reset_infos(self.num_envs, rows, [info for part in begun for info in part])
        self._ended[rows] = False
        self._started = True
        _put(infos, "action_mask", rows, self._masks(rows))
        return self._observation(), infos

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                          dict[str, Any]]:
        """Advance every sub-env by its action (see the class docstring)."""
        if not self._started:
            raise RuntimeError("call reset() before step() (and after a step or reset that "
                               "failed)")
        actions = self._check_actions(actions)
        n = self.num_envs
        rewards = np.zeros(n)
        terminated = np.zeros(n, dtype=bool)
        infos: dict[str, Any] = {}
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            resetting = np.flatnonzero(self._ended)
        else:
            if self.autoreset_mode == AutoresetMode.DISABLED and self._ended.any():
                ended = np.flatnonzero(self._ended).tolist()
                raise RuntimeError(f"sub-envs {ended} have ended their episodes: reset them "
                                   "with reset(options={'reset_mask': mask})")
            resetting = np.zeros(0, dtype=np.int64)
        stepping = np.flatnonzero(~self._ended) if len(resetting) else self._rows
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        parts = self._run(lambda group, rows: group.step(
            _within(resetting, group), rows, actions[group.start + rows], same_step), stepping)
        steps = _joined([part.steps for part in parts])
        rewards[stepping], terminated[stepping] = steps.reward, steps.terminated
        optimal = (None if parts[0].optimal is None
                   else np.concatenate([part.optimal for part in parts]))
        done = stepping[steps.terminated]
        begun = [info for part in parts for info in part.begun]
        if same_step and len(done):
            final_obs = np.full(n, None, dtype=object)
            final_obs[done] = [row for part in parts for row in part.final_obs]
            masks = np.concatenate([part.final_masks for part in parts])
            final_info = _step_infos(n, stepping, steps, masks_of=(done, masks),
                                     only=steps.terminated, optimal=optimal)
            infos = _reset_infos(n, done, begun)
            infos["final_obs"], infos["_final_obs"] = final_obs, _mask(n, done)
            infos["final_info"], infos["_final_info"] = final_info, _mask(n, done)
            _merge(infos, _step_infos(n, stepping, steps, only=~steps.terminated,
                                      optimal=optimal))
            self._ended[done] = False
        else:
            if len(resetting):
                infos = _reset_infos(n, resetting, begun)
            _merge(infos, _step_infos(n, stepping, steps, optimal=optimal))
            self._ended[resetting] = False
            self._ended[done] = True
        _put(infos, "action_mask", self._rows, self._masks(self._rows))
        truncated = np.zeros(n, dtype=bool)
        return self._observation(), rewards, terminated, truncated, infos

    def action_masks(self) -> np.ndarray:
        """(N, K) bool: each sub-env's valid branches now (``info["action_mask"]``)."""
        if not self._started:
            raise RuntimeError("call reset() before action_masks()")
        return self._masks(self._rows)

    def render(self) -> tuple | None:
        """Each sub-env's frame (``render_mode="rgb_array"``), else None."""
        if self.render_mode != "rgb_array":
            return None
        return tuple(env.render() for env in self.envs)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple:
        """Each sub-env's ``name``: called with the arguments if callable, else its value."""
        values = []
        for env in self.envs:
            value = getattr(env, name)
            values.append(value(*args, **kwargs) if callable(value) else value)
        return tuple(values)

    def get_attr(self, name: str) -> tuple:
        """Each sub-env's attribute ``name``."""
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values: Any) -> None:
        """Set ``name`` on every sub-env: one value each (a list or tuple of N) or the
        same value for all."""
        if not isinstance(values, list | tuple):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr needs {self.num_envs} values, got {len(values)}")
        for env, value in zip(self.envs, values, strict=True):
            setattr(env, name, value)

    def close_extras(self, **kwargs: Any) -> None:
        if self._pool is not None:
            self._pool.shutdown()
        for env in self.envs:
            env.close()

    # ----------------------------------------------------------------------- helpers
    def _seeds(self, seed: Any) -> list[int | None]:
        """One seed per sub-env from ``reset``'s: None, an int (numpy's too) or N seeds."""
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, numbers.Integral) and not isinstance(seed, bool):
            return [int(seed) + i for i in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"seed must be an int, None or {self.num_envs} seeds, got "
                             f"{len(seeds)}")
        return seeds

    def _reset_options(self, options: dict[str, Any]) -> list[dict[str, int]]:
        """Each sub-env's checked ``reset`` options (``IKBranchEnv.reset_options``) from
        ``options``' N entries per key."""
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise ValueError(f"unknown reset options {unknown}; the vector env takes "
                             f"reset_mask, {', '.join(RESET_OPTIONS)}")
        per_env: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for key, entries in options.items():
            if entries is None:
                continue
            if isinstance(entries, str | bytes) or not hasattr(entries, "__len__") or len(
                    entries) != self.num_envs:
                raise ValueError(f"reset option {key} must hold {self.num_envs} entries (one "
                                 f"per sub-env, None where drawn), got {entries!r}")
            for row, entry in enumerate(entries):
                per_env[row][key] = entry
        return [env.reset_options(option) for env, option in zip(self.envs, per_env,
                                                                  strict=True)]

    def _reset_mask(self, mask: object) -> np.ndarray:
        if not isinstance(mask, np.ndarray):
            raise TypeError(f"reset_mask must be a numpy array, got {type(mask).__name__}")
        if mask.shape != (self.num_envs,):
            raise ValueError(f"reset_mask must have shape ({self.num_envs},), got {mask.shape}")
        if mask.dtype != np.bool_:
            raise TypeError(f"reset_mask must be a bool array, got dtype {mask.dtype}")
        if not mask.any():
            raise ValueError("reset_mask must mark at least one sub-env to reset")
        return mask

    def _check_actions(self, actions: Any) -> np.ndarray:
        """``actions`` as (N,) int64, ``ValueError`` naming what is wrong: the shape, a
        non-integer dtype, a branch outside [0, K) (or, with ``enforce_masks``, outside its
        sub-env's mask)."""
        array = np.asarray(actions)
        if array.shape != (self.num_envs,):
            raise ValueError(f"actions must have shape ({self.num_envs},), one branch per "
                             f"sub-env, got {array.shape}")
        if array.dtype.kind not in "iu":
            raise ValueError(f"actions must be integers (branch indices), got dtype "
                             f"{array.dtype}")
        k = self.n_branches
        outside = np.flatnonzero((array < 0) | (array >= k))
        if len(outside):
            i = int(outside[0])
            raise ValueError(f"action {int(array[i])} of sub-env {i} is not a branch index "
                             f"in [0, {k})")
        actions = array.astype(np.int64)
        if self.enforce_masks:
            live = np.flatnonzero(~self._ended)
            masks = self._masks(live)
            bad = np.flatnonzero(~masks[np.arange(len(live)), actions[live]])
            if len(bad):
                i = int(live[bad[0]])
                raise ValueError(f"action {int(actions[i])} of sub-env {i} is outside its "
                                 f"mask (valid branches {np.flatnonzero(masks[bad[0]]).tolist()})")
        return actions

    def _run(self, work: Any, rows: np.ndarray) -> list[Any]:
        """``work(group, its rows)`` for every group, each in its thread (``rows``: sorted
        rows of the vector env; a group gets those it holds, numbered in the group): the
        results in group order."""
        groups = self._groups
        try:
            if self._pool is None:
                return [work(groups[0], rows)]
            futures = [self._pool.submit(work, group, _within(rows, group))
                       for group in groups[1:]]
            try:
                first = work(groups[0], _within(rows, groups[0]))
            finally:  # no group is left running when one fails
                wait(futures)
            return [first, *(future.result() for future in futures)]
        except BaseException:
            # Other sub-envs (another group's, or those before the failing one) may have
            # moved on: nothing holds until every sub-env is reset.
            self._started = False
            raise

    def _masks(self, rows: np.ndarray) -> np.ndarray:
        """(len(rows), K) the masks of sub-envs ``rows`` (sorted)."""
        return np.concatenate([group.episodes.masks(_within(rows, group))
                               for group in self._groups])

    def _observation(self) -> np.ndarray:
        """(N, size) every sub-env's observation (a copy)."""
        return np.concatenate([group.episodes.observation for group in self._groups])


@dataclass(frozen=True)
class _Stepped:
    """What :meth:`_Group.step` did, in the group's rows: the reset infos of the episodes
    it began (those that ended on the step before, or with same-step autoreset on this
    one), the steps paid, each sub-env's optimal return after them (None where not
    asked), and with same-step autoreset the last observations and masks of the
    episodes that ended."""

    begun: list[dict[str, Any]]
    steps: Steps
    optimal: np.ndarray | None
    final_obs: np.ndarray
    final_masks: np.ndarray


class _Group:
    """Sub-envs ``envs`` of a vector env (its rows from ``start``) and what advances them
    together: their scenes stacked in one filter, one batch of their episodes (rows
    numbered in the group). Groups share nothing they change: each may run in a thread
    of its own."""

    def __init__(self, envs: list[IKBranchEnv], start: int, whole: bool) -> None:
        first = envs[0]
        self.envs, self.start, self.stop = envs, start, start + len(envs)
        #: The group holds every sub-env of the vector env (one thread).
        self.whole = whole
        # One kernel call checks the paths of every sub-env, each in its own scene.
        self.stack = FilterStack([env.compiled_filter for env in envs])
        self.episodes = EpisodeBatch(len(envs), first.n_waypoints, first.pricer,
                                     first._observations, self.stack)
        for row, env in enumerate(envs):  # each sub-env runs its episode in its row
            env._episode = self.episodes.view(row, env.compiled_filter)
        self.rows = np.arange(len(envs))

    def reset(self, rows: np.ndarray, seeds: list[int | None],
              options: list[dict[str, int]]) -> list[dict[str, Any]]:
        """New episodes in ``rows`` (each with its seed and checked reset options),
        surveyed: their reset infos (without the masks)."""
        begun = self._begin(rows, seeds, options)
        self.episodes.survey(rows)
        return begun

    def step(self, resetting: np.ndarray, stepping: np.ndarray, actions: np.ndarray,
             same_step: bool) -> _Stepped:
        """Rows ``resetting`` begin new episodes, rows ``stepping`` take ``actions``; with
        ``same_step``, those whose episodes end begin new ones at once. Every row left in
        a new state is surveyed."""
        begun = self._begin(resetting, [None] * len(resetting))
        steps = self.episodes.advance(stepping, actions)
        optimal = (None if self.envs[0].optimal_return is None
                   else np.array([env.optimal_return for env in self.envs]))
        done = stepping[steps.terminated]
        final_obs = np.zeros((0, self.episodes.observation.shape[1]), dtype=np.float32)
        final_masks = np.zeros((0, self.episodes.valid.shape[2]), dtype=bool)
        if same_step and len(done):
            self.episodes.survey(done)  # their last observation
            final_obs = self.episodes.observation[done].copy()
            final_masks = self.episodes.masks(done)
            begun = self._begin(done, [None] * len(done))
            surveyed = np.concatenate([stepping[~steps.terminated], done])
        else:
            surveyed = self.rows if len(resetting) else stepping
        self.episodes.survey(surveyed)
        return _Stepped(begun, steps, optimal, final_obs, final_masks)

    def _begin(self, rows: np.ndarray, seeds: list[int | None],
               options: list[dict[str, int]] | None = None) -> list[dict[str, Any]]:
        if not len(rows):
            return []
        return begin_episodes([self.envs[row] for row in rows.tolist()], seeds, self.stack,
                              rows, options)


def _within(rows: np.ndarray, group: _Group) -> np.ndarray:
    """The sorted ``rows`` of a vector env that are ``group``'s, numbered in it."""
    if group.whole:  # the one group: every row, numbered alike
        return rows
    first, stop = np.searchsorted(rows, [group.start, group.stop])
    return rows[first:stop] - group.start


def _joined(parts: list[Steps]) -> Steps:
    """The steps of several groups as one, in group order."""
    if len(parts) == 1:
        return parts[0]
    joined = {field.name: np.concatenate([getattr(part, field.name) for part in parts])
              for field in fields(Steps) if field.name != "terms"}
    terms = {name: np.concatenate([part.terms[name] for part in parts])
             for name in parts[0].terms}
    return Steps(terms=terms, **joined)


def _reset_infos(n: int, rows: np.ndarray, begun: list[dict[str, Any]]) -> dict[str, Any]:
    """The reset infos ``begun`` of sub-envs ``rows``, batched (without the masks)."""
    infos: dict[str, Any] = {}
    # Each key's rows and values (keys in the order the rows first name them), then one
    # _put a key.
    columns: dict[str, tuple[list[int], list[Any]]] = {}
    for row, info in zip(rows.tolist(), begun, strict=True):
        for key, value in info.items():
            named, values = columns.setdefault(key, ([], []))
            named.append(row)
            values.append(value)
    for key, (named, values) in columns.items():
        _put(infos, key, np.array(named), np.array(values), n=n)
    return infos


def _autoreset_mode(value: str | AutoresetMode) -> AutoresetMode:
    """An ``AutoresetMode`` from itself, its value ("SameStep") or its name ("same_step")."""
    if isinstance(value, AutoresetMode):
        return value
    for mode in AutoresetMode:
        if isinstance(value, str) and value in (mode.value, mode.name, mode.name.lower()):
            return mode
    modes = ", ".join(f"{m.name.lower()!r}" for m in AutoresetMode)
    raise ValueError(f"autoreset_mode must be one of {modes} (or an AutoresetMode), got "
                     f"{value!r}")


def _mask(n: int, rows: np.ndarray) -> np.ndarray:
    mask = np.zeros(n, dtype=bool)
    mask[rows] = True
    return mask


def _put(infos: dict[str, Any], key: str, rows: np.ndarray, values: np.ndarray,
         n: int | None = None, present: np.ndarray | None = None) -> None:
    """``infos[key][rows] = values`` and ``infos["_" + key][rows] = True``, the arrays made
    as ``VectorEnv._add_info`` makes them (zeros of the values' dtype and shape);
    ``present`` is the rows' mask where the caller has it (a new key stores a copy)."""
    if key not in infos:
        count = len(infos[next(iter(infos))]) if n is None and infos else n
        if count is None:
            count = len(rows)
        values = np.asarray(values)
        infos[key] = np.zeros((count, *values.shape[1:]), dtype=values.dtype)
        infos[key][rows] = values
        infos["_" + key] = np.zeros(count, dtype=bool) if present is None else present.copy()
        if present is None:
            infos["_" + key][rows] = True
        return
    infos[key][rows] = values
    infos["_" + key][rows] = True


def _merge(infos: dict[str, Any], more: dict[str, Any]) -> None:
    """Add the batched ``more`` into ``infos`` (keys both have: rows of ``more``'s mask)."""
    for key, value in more.items():
        if key.startswith("_"):
            continue
        mask = more["_" + key]
        if key in infos:
            infos[key][mask] = value[mask]
            infos["_" + key] |= mask
        else:
            infos[key], infos["_" + key] = value, mask


def _step_infos(n: int, rows: np.ndarray, steps: Steps,
                masks_of: tuple[np.ndarray, np.ndarray] | None = None,
                only: np.ndarray | None = None,
                optimal: np.ndarray | None = None) -> dict[str, Any]:
    """The batched step infos of ``rows`` (those with ``only``), as each sub-env's
    ``IKBranchEnv.step`` info batched by ``SyncVectorEnv``; ``masks_of`` (rows, masks)
    adds their action masks, ``optimal`` (N,) their episodes' optimal returns."""
    pick = slice(None) if only is None else only
    picked = rows[pick]
    infos: dict[str, Any] = {}
    if not len(picked):
        return infos
    columns = {"waypoint": steps.waypoint, "branch": steps.branch, "travel": steps.travel,
               "time": steps.time, **steps.terms, "collision": steps.collision,
               "invalid": steps.invalid}
    present = _mask(n, picked)  # made once for every column
    for key, value in columns.items():
        _put(infos, key, picked, value[pick], n=n, present=present)
    ended = steps.terminated[pick]
    if ended.any():
        _put(infos, "is_success", picked[ended], steps.success[pick][ended], n=n)
    if optimal is not None:
        _put(infos, "optimal_return", picked, optimal[picked], n=n)
    if masks_of is not None:
        _put(infos, "action_mask", masks_of[0], masks_of[1], n=n)
    return infos
