"""Every registered id follows the Gymnasium and SB3 APIs: checkers, spaces, seeding,
pickling, vector envs with action masks, rendering."""

from __future__ import annotations

import itertools
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from gymnasium.utils.passive_env_checker import env_render_passive_checker
from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported
from stable_baselines3.common.env_checker import check_env as sb3_check_env
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import SubprocVecEnv

from tests.envs.env_cases import IDS, assert_same, choose, make, rollout, same_info


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_check_env_without_warnings(env_id):
    # Rendering, which the checker would do at the default size in an env of its own, is
    # Gymnasium's render check in test_rgb_array_render_shows_a_real_frame.
    env = make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gym_check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", IDS)
def test_sb3_check_env_without_warnings(env_id):
    env = make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_check_env(env.unwrapped, warn=True)
    assert is_masking_supported(env)


@pytest.mark.parametrize("env_id", IDS)
def test_masked_rollouts_stay_in_the_observation_space(env_id):
    env = make(env_id)
    base = env.unwrapped
    for _, obs, *rest in rollout(env, seed=3, action_seed=4, episodes=3):
        assert obs.dtype == np.float32 and obs.shape == env.observation_space.shape
        assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
        if rest and rest[-1].get("is_success") is not None:
            assert not rest[-1]["invalid"]  # masked actions are never invalid
    # Every layout slice is used once: the named slices tile the observation.
    spans = sorted(base.observation_layout.values())
    assert spans[0][0] == 0 and spans[-1][1] == env.observation_space.shape[0]
    assert all(a[1] == b[0] for a, b in itertools.pairwise(spans))


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_and_actions_give_the_same_trajectory(env_id):
    env = make(env_id)
    first = rollout(env, seed=11, action_seed=1, p_unmasked=0.3)
    rollout(env, seed=12, action_seed=2, episodes=2, p_unmasked=0.3)  # warm caches, other tasks
    again = rollout(env, seed=11, action_seed=1, p_unmasked=0.3)
    fresh = rollout(make(env_id), seed=11, action_seed=1, p_unmasked=0.3)
    assert_same(first, again)
    assert_same(first, fresh)
    other = rollout(env, seed=13, action_seed=1)
    assert not np.array_equal(first[0][1], other[0][1])  # seeds matter


@pytest.mark.parametrize("env_id", IDS)
def test_pickles_and_continues_identically_mid_episode(env_id):
    env = make(env_id, n_waypoints=4)
    base = env.unwrapped
    pickle.loads(pickle.dumps(base))  # before any reset, too
    base.reset(seed=5)
    rng = np.random.default_rng(0)
    base.step(choose(base, rng, 0.0))
    copy = pickle.loads(pickle.dumps(base))
    assert copy.index == base.index and np.array_equal(copy.q, base.q)
    for _ in range(2):  # continue both, then a fresh episode from each one's np_random
        actions = []
        while base.index < base.task.n_waypoints:
            actions.append(choose(base, rng, 0.2))
            a, b = base.step(actions[-1]), copy.step(actions[-1])
            assert np.array_equal(a[0], b[0]) and a[1:4] == b[1:4]
            assert same_info(a[4], b[4])
        assert np.array_equal(base.reset()[0], copy.reset()[0])


def _masked_actions(masks, rng) -> np.ndarray:
    masks = np.asarray(masks)
    return np.array([rng.choice(np.flatnonzero(row)) for row in masks])


@pytest.mark.parametrize("mode", ["sync", "async"])
@pytest.mark.parametrize("env_id", IDS)
def test_make_vec_reaches_the_masks(env_id, mode):
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, **{"n_waypoints": 2,
                                                                        "lookahead": 1})
    k = venv.single_action_space.n
    try:
        obs, info = venv.reset(seed=0)
        assert obs.shape == (2, *venv.single_observation_space.shape)
        rng = np.random.default_rng(0)
        ended = 0
        for _ in range(5):
            masks = info["action_mask"]  # batched from each env's info: no round trip
            np.testing.assert_array_equal(masks, np.stack(venv.call("action_masks")))
            assert masks.shape == (2, k) and masks.dtype == bool and masks.any(axis=1).all()
            obs, reward, terminated, _, info = venv.step(_masked_actions(masks, rng))
            assert venv.observation_space.contains(obs) and np.all(np.isfinite(reward))
            ended += int(terminated.sum())
        assert ended >= 2  # two-waypoint episodes: both sub-envs ended (and reset) at least once
    finally:
        venv.close()


@pytest.mark.parametrize("env_id", IDS)
def test_sb3_subproc_vec_env_reaches_the_masks(env_id):
    venv = make_vec_env(env_id, n_envs=2, seed=0, vec_env_cls=SubprocVecEnv,
                        vec_env_kwargs={"start_method": "fork"},
                        env_kwargs={"n_waypoints": 2, "lookahead": 1})
    try:
        assert is_masking_supported(venv)
        obs = venv.reset()
        rng = np.random.default_rng(0)
        for _ in range(4):
            masks = get_action_masks(venv)
            assert masks.shape == (2, venv.action_space.n) and masks.any(axis=1).all()
            assert np.array_equal(masks, np.stack(venv.env_method("action_masks")))
            obs, _, _, info = venv.step(_masked_actions(masks, rng))
            assert all(venv.observation_space.contains(row) for row in obs)
            assert not any(i.get("invalid", False) for i in info)
    finally:
        venv.close()


@pytest.mark.parametrize("env_id", IDS)
def test_rgb_array_render_shows_a_real_frame(env_id):
    env = make(env_id, render_mode="rgb_array", width=96, height=72)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        frame = env_render_passive_checker(env.unwrapped)  # metadata, mode, frame type
    assert frame.shape == (72, 96, 3) and frame.dtype == np.uint8
    assert frame.std() > 10.0  # not blank
    env.close()
    env.close()  # closing twice is harmless
    plain = make(env_id)
    plain.reset(seed=0)
    assert plain.render() is None  # no render mode: nothing drawn


def test_an_id_that_draws_clutter_takes_another_scene():
    # Anthropomorphic-v2 registers scene_seed=None (a new clutter per episode); asked for a
    # scene without clutter it builds that scene, and the seed has nothing to draw.
    env = gym.make("IKBranch/Anthropomorphic-v2", scene="empty")
    obs, info = env.reset(seed=0)
    base = env.unwrapped
    assert base._clutter is None and "scene_seed" not in info
    assert not any(base.model.geom(g).name.startswith("clutter") for g in range(base.model.ngeom))
    assert env.observation_space.contains(obs)
