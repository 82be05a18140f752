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


def least_onward_travel(base, moves: int, paths_collide, continuity: bool = True) -> np.ndarray:
    """(K,) by enumeration, per branch of the env's next waypoint: the least travel of the
    next ``moves`` moves (fewer where the task ends sooner) along paths that
    ``paths_collide(start, ends)`` calls free, each ending in a free configuration and none
    reconfiguring the arm inside a process segment (``continuity=False``: those too); +inf
    for branches outside the mask or
    whose own path collides, for those with no such way on, and at the task's last
    waypoint."""
    ladder, i = base.ladder, base.index
    n, k = ladder.n_waypoints, base.arm.n_branches
    memo: dict[tuple[int, int, int], float] = {}

    def onward(w: int, c: int, left: int) -> float:
        if left == 0 or w + 1 >= n:
            return 0.0
        if (w, c, left) not in memo:
            blocked = ladder.blocked(ladder.candidates[w], w + 1)[c] & continuity
            ends = np.flatnonzero(ladder.valid[w + 1] & ~ladder.endpoint_collision[w + 1]
                                  & ~blocked)
            best = np.inf
            if len(ends):
                start, targets = ladder.candidates[w][c], ladder.candidates[w + 1][ends]
                free = ~paths_collide(start, targets)
                travel = base.cost.travel(start, targets)
                for d, step, is_free in zip(ends, travel, free, strict=True):
                    if is_free:
                        best = min(best, step + onward(w + 1, int(d), left - 1))
            memo[w, c, left] = best
        return memo[w, c, left]

    out = np.full(k, np.inf)
    if i + 1 >= n:
        return out
    for a in np.flatnonzero(base.action_masks()):
        if i == 0 and ladder.task.free_start:  # the arm starts in the branch it picks
            hit = ladder.endpoint_collision[0, a]
        else:
            hit = paths_collide(base.q, ladder.candidates[i][a : a + 1])[0]
        if not hit:
            out[a] = onward(i, int(a), moves)
    return out


def raw_onward(base) -> tuple[np.ndarray, np.ndarray]:
    """The compiled stage's own float64 values for the env's state now: (K,) onward free
    travel of one move and of ``onward_moves`` moves, before they are scaled, capped at 1
    and rounded to float32 in the observation (``envs.stepping._onward``)."""
    from ikbranch_gym.envs import stepping

    k, layout = base.arm.n_branches, base.observation_layout
    obs = base._episode.observation[0]
    collision = obs[slice(*layout["slot0/path_collision"])][None].astype(bool)
    one, several = np.full((1, k), np.inf), np.full((1, k), np.inf)
    stepping._onward(base._episode._episodes, base.compiled_filter._bound,
                     np.zeros(1, dtype=np.int64), collision, one, several)
    return one[0], several[0]


IDS = envs.ENV_IDS
