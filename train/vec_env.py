"""stable-baselines3's ``VecEnv`` over the natively batched vector env, in one process.

:class:`NativeVecEnv` hands SB3 (PPO, MaskablePPO, ``VecNormalize``, the evaluation
callbacks) an :class:`envs.vector_env.IKBranchVectorEnv` as if it were the
``DummyVecEnv`` of ``Monitor``-wrapped single envs that ``make_vec_env`` builds — the
same observations, rewards (float32), dones, per-env infos with ``terminal_observation``,
``TimeLimit.truncated`` and Monitor's ``episode`` record, and seeds (``seed(s)``: sub-env
i gets s + i) — with no subprocess and no per-env Python loop. The action masks
MaskablePPO asks for every step (``env_method("action_masks")``) come from the last
step's ``info["action_mask"]``: no round trip.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn

from ikbranch_gym.envs.vector_env import IKBranchVectorEnv


def make_native_vec_env(env_id: str, n_envs: int, env_kwargs: dict[str, Any] | None = None,
                        seed: int | None = None, threads: int = 1) -> NativeVecEnv:
    """``n_envs`` sub-envs of ``env_id`` (with ``env_kwargs``) as an SB3 ``VecEnv``;
    ``seed``: sub-env i is seeded with ``seed + i`` at the first reset, as SB3's
    ``make_vec_env`` seeds its envs; ``threads``: the vector env's (its docstring, the
    same data whatever the number)."""
    import ikbranch_gym.envs  # noqa: F401  (registers the ids)

    venv = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode=AutoresetMode.SAME_STEP, threads=threads,
                        **(env_kwargs or {}))
    # The vector entry point of every id makes an IKBranchVectorEnv.
    vec_env = NativeVecEnv(cast(IKBranchVectorEnv, venv))
    if seed is not None:
        vec_env.seed(seed)
    return vec_env


class NativeVecEnv(VecEnv):
    """An ``IKBranchVectorEnv`` (same-step autoreset) as SB3's ``VecEnv`` (module
    docstring)."""

    def __init__(self, venv: IKBranchVectorEnv) -> None:
        if not isinstance(venv.unwrapped, IKBranchVectorEnv):
            raise TypeError(f"NativeVecEnv wraps an IKBranchVectorEnv, got {type(venv).__name__}")
        if venv.metadata.get("autoreset_mode") != AutoresetMode.SAME_STEP:
            raise ValueError("NativeVecEnv needs the vector env in same-step autoreset mode "
                             "(SB3 resets an env within the step that ends its episode)")
        self.venv = venv
        self._base = venv.unwrapped
        self._masks: np.ndarray | None = None
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        # As DummyVecEnv: the sub-env's metadata (render modes, fps).
        self.metadata = self._base.envs[0].metadata
        # Monitor's bookkeeping per sub-env: this episode's return (summed as Monitor sums
        # it, in float64, step by step) and length, and the clock its times count from.
        self._returns = np.zeros(self.num_envs)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._t_start = time.time()

    # ---------------------------------------------------------------------- VecEnv API
    def reset(self) -> np.ndarray:
        seeds = None if all(seed is None for seed in self._seeds) else list(self._seeds)
        observations, infos = self.venv.reset(seed=seeds)
        self.reset_infos = _per_env(infos, self.num_envs)
        self._masks = infos["action_mask"]
        self._returns[:], self._lengths[:] = 0.0, 0
        self._reset_seeds()
        self._reset_options()
        return observations

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        observations, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        self._returns += rewards
        self._lengths += 1
        per_env = _per_env(infos, self.num_envs)
        step_infos: list[dict[str, Any]] = []
        done_rows = np.flatnonzero(dones)
        finals = _per_env(infos.get("final_info", {}), self.num_envs) if len(done_rows) else []
        for i in range(self.num_envs):
            if dones[i]:
                info = dict(finals[i])
                info["episode"] = {"r": round(float(self._returns[i]), 6),
                                   "l": int(self._lengths[i]),
                                   "t": round(time.time() - self._t_start, 6)}
                self._returns[i], self._lengths[i] = 0.0, 0
                info["terminal_observation"] = infos["final_obs"][i]
                self.reset_infos[i] = {key: value for key, value in per_env[i].items()
                                       if key not in ("final_obs", "final_info")}
            else:
                info = per_env[i]
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            step_infos.append(info)
        self._masks = infos["action_mask"]
        return observations, rewards.astype(np.float32), dones, step_infos

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self._base.envs[i], attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for i in self._get_indices(indices):
            setattr(self._base.envs[i], attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        rows = list(self._get_indices(indices))
        if method_name == "action_masks" and self._masks is not None:
            return [self._masks[i].copy() for i in rows]  # the last step's info: no round trip
        return [getattr(self._base.envs[i], method_name)(*method_args, **method_kwargs)
                for i in rows]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        # Monitor's record is in every info (``episode``), as if each sub-env were wrapped.
        return [wrapper_class is Monitor] * len(list(self._get_indices(indices)))

    def get_images(self) -> Sequence[np.ndarray | None]:
        frames = self.venv.render()
        return [None] * self.num_envs if frames is None else list(frames)

    def action_masks(self) -> np.ndarray:
        """(N, K) the masks of every sub-env now."""
        return self._base.action_masks()


def _per_env(infos: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """Batched infos (an array per key, ``_key`` masks; nested dicts alike) as one dict per
    env, with the keys that env reported."""
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in infos.items():
        if key.startswith("_"):
            continue
        mask = infos.get("_" + key)
        rows: Iterable[int] = range(n) if mask is None else np.flatnonzero(mask).tolist()
        if isinstance(value, dict):
            nested = _per_env(value, n)
            for i in rows:
                out[i][key] = nested[i]
            continue
        for i in rows:
            out[i][key] = value[i]
    return out
