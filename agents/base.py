"""What every baseline shares: SB3's ``predict`` signature over an env it reads directly.

The analytic baselines do not learn from observations: they read the task (candidates,
validity, prices) from the :class:`~envs.ik_branch_env.IKBranchEnv` they were made with,
exactly as an offline planner would. ``predict`` still takes SB3's arguments, so one loop
evaluates baselines and trained models alike. Which branches a policy may choose comes
from the outermost wrapper (:func:`action_mask`): a wrapper that forbids a branch is obeyed
by every policy, the baselines included.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.tasks import Task


class Policy(Protocol):
    """SB3's ``predict``: the one interface evaluation relies on."""

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
        action_masks: np.ndarray | None = None,
    ) -> tuple[np.ndarray, Any]: ...


def action_mask(env: gym.Env, info: Mapping[str, Any] | None = None) -> np.ndarray | None:
    """(K,) bool: the branches a policy may choose now, as the outermost wrapper has them.

    ``action_masks()`` found through the wrappers (``env.get_wrapper_attr``: a wrapper's
    own method before the env's; sb3-contrib's protocol, so what MaskablePPO trained on),
    narrowed by ``info["action_mask"]`` of the latest ``reset`` or ``step`` when ``info``
    is given (a wrapper may rewrite either; a branch is offered when both allow it). None
    when the env offers neither. Never ``env.unwrapped``: that would skip the wrappers.
    """
    mask: np.ndarray | None = None
    try:
        method = env.get_wrapper_attr("action_masks")
    except AttributeError:
        method = None
    if callable(method):
        mask = np.asarray(method(), dtype=bool)
    if info is not None and "action_mask" in info:
        reported = np.asarray(info["action_mask"], dtype=bool)
        if mask is not None and mask.shape != reported.shape:
            raise ValueError(f"action_masks() has shape {mask.shape} but info['action_mask'] "
                             f"{reported.shape}: a wrapper changed one and not the other")
        mask = reported if mask is None else mask & reported
    return mask


def unwrap(env: gym.Env) -> IKBranchEnv:
    """The :class:`IKBranchEnv` under any gymnasium wrappers (``gym.make`` adds some)."""
    base = env.unwrapped
    if not isinstance(base, IKBranchEnv):
        raise TypeError(f"baselines need an IKBranchEnv, got {type(base).__name__}")
    return base


class Baseline:
    """An analytic policy bound to one env; subclasses implement :meth:`choose`.

    A new episode is noticed from ``episode_start``, from the env's task object changing or
    from its waypoint index going back (SB3 loops do not always pass ``episode_start``),
    and :meth:`on_episode` runs once per episode before the first choice: planners plan
    there, so planning is part of the first ``predict`` call and amortises over the episode.
    """

    #: Name in ``agents.BASELINES``.
    name: str = ""

    def __init__(self, env: gym.Env) -> None:
        self.env = unwrap(env)
        #: The env as given, wrappers included: its observations are what ``predict`` gets
        #: and its outermost wrapper's ``action_masks()`` the branches it may choose.
        self.wrapped = env
        self.observation_shape = env.observation_space.shape
        self._task: Task | None = None
        self._last_index = 0

    # ------------------------------------------------------------------ SB3 interface
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
        action_masks: np.ndarray | None = None,
    ) -> tuple[np.ndarray, Any]:
        """The branch for the env's next waypoint; ``(action, state)`` like SB3.

        An unbatched observation gives a 0-d action array, a batch of one a (1,) array
        (SB3's convention). The baseline acts on its own env, so larger batches are refused.
        """
        shape = self.observation_shape
        assert shape is not None  # IKBranchEnv's observation space is a Box
        batched = np.ndim(observation) == len(shape) + 1
        if batched and np.shape(observation)[0] != 1:
            raise ValueError("a baseline acts on the one env it was made with: batch size 1")
        env = self.env
        if env.task is None:
            raise RuntimeError("reset the env before asking a baseline for an action")
        # A new episode: flagged, or a new task object, or the env went back in the task
        # (a generator could hand out the same Task object twice).
        if np.any(episode_start) or env.task is not self._task or env.index < self._last_index:
            self._task = env.task
            self.on_episode()
        self._last_index = env.index
        if env.index >= env.task.n_waypoints:  # episode over: any action, as the env allows
            branch = 0
        else:
            outer = action_mask(self.wrapped)  # a wrapper may forbid branches
            mask = env.action_masks() if outer is None else outer
            # SB3 semantics: the caller's mask has the last word (narrowing, never widening).
            if action_masks is not None:
                mask = mask & np.asarray(action_masks, dtype=bool).reshape(-1)
            branch = int(self.choose(env.index, mask))
            if not mask[branch]:
                raise AssertionError(f"{self.name} chose masked branch {branch}")
        action = np.array(branch, dtype=np.int64)
        return (action[None] if batched else action), state

    # -------------------------------------------------------------------- subclasses
    def on_episode(self) -> None:
        """Called once at the start of every episode (the env has just been reset)."""

    def choose(self, waypoint: int, mask: np.ndarray) -> int:
        """The branch for ``waypoint`` among ``mask`` (K,) bool; never a masked one."""
        raise NotImplementedError

    # ----------------------------------------------------------------------- helpers
    def current_row(self, waypoint: int) -> int:
        """Row of ``edge_rewards(waypoint)`` the arm stands in: 0 for the task's start,
        else the branch of ``waypoint − 1`` whose configuration the arm holds (found from
        the env's state, so it is right whoever chose the earlier actions)."""
        if waypoint == 0:
            return 0
        env = self.env
        assert env.candidates is not None  # set by reset; ``predict`` refuses to act before
        rows = np.flatnonzero(np.all(env.candidates[waypoint - 1] == env.q, axis=-1))
        if len(rows) == 0:
            raise RuntimeError(f"the arm stands at no candidate of waypoint {waypoint - 1}")
        return int(rows[0])  # duplicate candidates are the same configuration: same prices

    def move_travel(self, waypoint: int) -> np.ndarray:
        """(K,) travel of moving from where the arm stands to each branch of ``waypoint``
        (NaN for invalid ones; zero at a free start): the env's own prices."""
        assert self.env.ladder is not None  # set by reset; ``predict`` refuses to act before
        return self.env.ladder.travel_from(self.env.q, waypoint)


def first_within(costs: np.ndarray, tolerance: float = 1e-9) -> int:
    """Flat index of the first entry within ``tolerance`` (relative) of the least finite
    cost: ties broken by index, immune to round-off (1.1→2.1 and 1.2→2.2 of the paper
    differ by ~1e-13 rad)."""
    flat = np.ravel(costs)
    finite = np.isfinite(flat)
    best = flat[finite].min()
    slack = tolerance * max(1.0, abs(best))
    return int(np.flatnonzero(finite & (flat <= best + slack))[0])
