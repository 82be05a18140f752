"""Shared helpers of the environment tests (``test_env_*.py``): small, fast env settings and
seeded rollouts that record everything a comparison needs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import ikbranch_gym.envs as envs

#: Small episodes keep a test of every id fast; the
#: checks that depend on defaults build their envs without these.
FAST = {"n_waypoints": 3, "lookahead": 1}

INFO_TERMS = ("reward_travel", "reward_time", "reward_collision", "reward_invalid",
              "reward_unfinished")


def make(env_id: str, **kwargs) -> gym.Env:
    return gym.make(env_id, **{**FAST, **kwargs})


def choose(base, rng: np.random.Generator, p_unmasked: float) -> int:
    """A uniformly random valid branch; with probability ``p_unmasked`` any branch."""
    if rng.random() < p_unmasked:
        return int(rng.integers(base.arm.n_branches))
    return int(rng.choice(np.flatnonzero(base.action_masks())))


def rollout(env: gym.Env, seed: int, action_seed: int, episodes: int = 1,
            p_unmasked: float = 0.0) -> list[tuple]:
    """Episodes from ``reset(seed=seed)`` (then unseeded resets): per step the action,
    observation, reward, flags and info."""
    base, rng = env.unwrapped, np.random.default_rng(action_seed)
    record = []
    for episode in range(episodes):
        obs, info = env.reset(seed=seed if episode == 0 else None)
        record.append(("reset", obs, info))
        done = False
        while not done:
            action = choose(base, rng, p_unmasked)
            obs, reward, terminated, truncated, info = env.step(action)
            record.append((action, obs, reward, terminated, truncated, info))
            done = terminated or truncated
    return record


def assert_same(a: list[tuple], b: list[tuple]) -> None:
    """Bit-identical records (observations, rewards, flags, infos: their action masks as
    arrays, every other entry as the Python value it is)."""
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x[0] == y[0]
        assert x[1].dtype == y[1].dtype and np.array_equal(x[1], y[1])
        assert x[2:-1] == y[2:-1]
        assert same_info(x[-1], y[-1])


def same_info(a: dict, b: dict) -> bool:
    """Two infos equal, their ``action_mask`` arrays elementwise (and of one dtype)."""
    if a.keys() != b.keys():
        return False
    for key, value in a.items():
        if isinstance(value, np.ndarray):
            if value.dtype != b[key].dtype or not np.array_equal(value, b[key]):
                return False
        elif value != b[key]:
            return False
    return True


IDS = envs.ENV_IDS
