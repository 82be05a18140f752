"""The compiled stages' path verdicts: a turn copy of a path takes its proved verdict, and
every verdict is the one the filter gives that path itself."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs  # noqa: F401  (registers the ids)
from ikbranch_gym.envs import stepping
from ikbranch_gym.envs.models import CollisionChecker
from ikbranch_gym.envs.models.filter import COUNTERS, path_steps
from ikbranch_gym.envs.models.filter.kernels import BY_MUJOCO

MUJOCO = COUNTERS.index("mujoco")


def _env(env_id: str, seed: int):
    env = gym.make(env_id)
    env.reset(seed=seed)  # a clutter laid, its scene token set
    return env, env.unwrapped


def _own_verdicts(base, starts, ends):
    """Each path checked by itself: no memo, no copies."""
    steps = np.empty(len(ends), dtype=np.int64)
    path_steps(starts, ends, base.checker.lever, base.checker.resolution, steps)
    return np.array([base.compiled_filter.paths(starts[m : m + 1], ends[m : m + 1],
                                                steps[m : m + 1], False)[0] >= 0
                     for m in range(len(ends))])


def _turns(base, rng):
    """Whole turns (rad) of random revolute joints: added to both ends, a path's copy."""
    return 2.0 * np.pi * rng.integers(-1, 2, size=base.arm.dof) * base.arm.revolute_mask


@pytest.mark.parametrize("env_id", ["IKBranch/UR5e-v3", "IKBranch/KukaKR6-v2"])
def test_turn_copies_of_paths_take_the_verdicts_each_path_has(env_id):
    env, base = _env(env_id, 3)
    rng = np.random.default_rng(0)
    lower, upper = base.arm.joint_limits[:, 0], base.arm.joint_limits[:, 1]
    starts = rng.uniform(lower, upper, size=(300, base.arm.dof))
    starts = starts[~base.checker.rows_collide(starts)][:60]
    ends = np.clip(starts + rng.uniform(-0.6, 0.6, size=starts.shape), lower, upper)
    # Each path, and three copies of every path turned alike at both ends, in one call.
    shifts = [_turns(base, rng) for _ in range(3)]
    all_starts = np.concatenate([starts, *(starts + shift for shift in shifts)])
    all_ends = np.concatenate([ends, *(ends + shift for shift in shifts)])
    episodes, bound = base._episode._episodes, base.compiled_filter._bound
    counts = base._episode._copies[4]
    before = int(counts[0])
    rows = np.zeros(len(all_ends), dtype=np.int64)
    shared = stepping._paths_collide(episodes, bound, rows, all_starts, all_ends)
    expected = _own_verdicts(base, all_starts, all_ends)
    np.testing.assert_array_equal(shared, expected)
    assert expected.any() and not expected.all()
    # Four paths a key: the copies were not checked again (a key per path, and far fewer
    # than the paths; rounding may key a copy apart, which only costs a check).
    assert len(starts) <= int(counts[0]) - before < 2 * len(starts)
    env.close()


def test_a_copy_of_a_path_mujoco_helped_decide_is_checked_itself():
    env, base = _env("IKBranch/UR5e-v3", 3)
    filt = base.compiled_filter
    rng = np.random.default_rng(1)
    lower, upper = base.arm.joint_limits[:, 0], base.arm.joint_limits[:, 1]
    # A configuration on the edge of a contact (bisected between a free and a colliding
    # one by MuJoCo's verdicts): neither proof holds there, MuJoCo decides.
    mujoco = CollisionChecker(base.checker.model, dof=base.arm.dof, backend="loop").collides
    grazing = None
    for _ in range(200):
        q = rng.uniform(lower, upper, size=(2, base.arm.dof))
        if mujoco(q[0]) or not mujoco(q[1]):
            continue
        low, high = 0.0, 1.0
        for _ in range(60):
            middle = (low + high) / 2
            inside = mujoco(q[0] + middle * (q[1] - q[0]))
            low, high = (low, middle) if inside else (middle, high)
        edge = q[0] + high * (q[1] - q[0])
        if filt.collide_how(edge[None])[1][0] == BY_MUJOCO:
            grazing = edge
            break
    assert grazing is not None
    start = grazing[None]
    end = start.copy()
    end[0, 0] += 1e-9
    turn = 2.0 * np.pi * base.arm.revolute_mask
    starts, ends = np.concatenate([start, start + turn]), np.concatenate([end, end + turn])
    episodes, bound = base._episode._episodes, filt._bound
    called = int(filt.counters[MUJOCO])
    shared = stepping._paths_collide(episodes, bound, np.zeros(2, dtype=np.int64), starts,
                                     ends)
    # Both went to MuJoCo: the copy did not take a verdict MuJoCo helped reach.
    assert int(filt.counters[MUJOCO]) - called >= 2
    np.testing.assert_array_equal(shared, _own_verdicts(base, starts, ends))
    verdicts = base._episode._copies[2]
    assert (verdicts == stepping.COPY_UNPROVED).sum() == 1
    env.close()


@pytest.mark.parametrize("env_id", ["IKBranch/UR5e-v3", "IKBranch/KukaKR6-v2"])
def test_episodes_are_the_same_with_and_without_turn_copies(env_id):
    runs = []
    for copies in (1.0, 0.0):
        env = gym.make(env_id)
        base = env.unwrapped
        base._episode._numbers[stepping.TURN_COPIES] = copies
        seen = []
        for seed in range(6):
            obs, info = env.reset(seed=seed)
            rng = np.random.default_rng(seed)
            seen.append(obs)
            terminated = False
            while not terminated:
                action = int(rng.choice(np.flatnonzero(info["action_mask"])))
                obs, reward, terminated, _, info = env.step(action)
                seen += [obs, np.array([reward])]
        runs.append(np.concatenate(seen))
        env.close()
    assert base._episode._numbers[stepping.TURN_COPIES] == 0.0
    np.testing.assert_array_equal(runs[0], runs[1])
