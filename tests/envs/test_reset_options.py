"""``reset(options=…)``: a named scene and a named task; opt-in ``info["optimal_return"]``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode

import ikbranch_gym.envs  # noqa: F401  (registers the ids)
from ikbranch_gym.agents import make_baseline
from tests.envs.env_cases import FAST

CLUTTER = "IKBranch/Anthropomorphic-v2"  # a new clutter every episode
CELL = "IKBranch/ToolTransfer-v1"  # a fixed scene, tasks drawn from np_random


def _verdicts(env: gym.Env, rows: np.ndarray) -> np.ndarray:
    return env.unwrapped.checker.collides(rows)


def _rows(env: gym.Env, count: int) -> np.ndarray:
    arm = env.unwrapped.arm
    rng = np.random.default_rng(0)
    return rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(count, arm.dof))


def test_scene_seed_lays_the_clutter_another_reset_drew():
    drawn, named = gym.make(CLUTTER, **FAST), gym.make(CLUTTER, **FAST)
    _, info = drawn.reset(seed=7)
    scene = info["scene_seed"]
    _, named_info = named.reset(seed=99, options={"scene_seed": scene})
    assert named_info["scene_seed"] == scene
    rows = _rows(drawn, 2000)
    verdicts = _verdicts(drawn, rows)
    assert 0 < verdicts.sum() < len(rows)
    np.testing.assert_array_equal(_verdicts(named, rows), verdicts)
    named.reset(seed=99, options={"scene_seed": scene + 1})
    assert not np.array_equal(_verdicts(named, rows), verdicts)  # another clutter


def test_named_scene_and_task_give_the_same_episode_whatever_the_seed():
    env = gym.make(CLUTTER, **FAST)
    options = {"scene_seed": 5, "task_seed": 42}
    one = env.reset(seed=1, options=options)
    task = env.unwrapped.task
    two = env.reset(seed=2, options=options)
    assert data_equivalence(one, two, exact=True)
    np.testing.assert_array_equal(env.unwrapped.task.poses, task.poses)
    assert two[1]["task_seed"] == 42 and two[1]["scene_seed"] == 5
    other = env.reset(seed=1, options={"scene_seed": 5, "task_seed": 43})
    assert not np.array_equal(other[0], one[0])


def test_task_seed_on_a_fixed_scene_replaces_the_draw_from_np_random():
    env = gym.make(CELL)
    env.reset(seed=1, options={"task_seed": 8})
    first = env.unwrapped.task.poses.copy()
    env.reset(seed=2, options={"task_seed": 8})
    np.testing.assert_array_equal(env.unwrapped.task.poses, first)
    env.reset(seed=1)
    assert not np.array_equal(env.unwrapped.task.poses, first)


@pytest.mark.parametrize(("env_id", "options", "message"), [
    (CLUTTER, {"scene": 3}, "unknown reset options ['scene']"),
    (CLUTTER, {"task_seed": -1}, "task_seed must be an integer >= 0"),
    (CLUTTER, {"scene_seed": 2.5}, "scene_seed must be an integer >= 0"),
    (CLUTTER, {"scene_seed": True}, "scene_seed must be an integer >= 0"),
    (CELL, {"scene_seed": 3}, "needs an env that lays a clutter per episode"),
    (CELL, ["task_seed"], "reset options must be a dict"),
])
def test_bad_reset_options_are_errors(env_id, options, message):
    env = gym.make(env_id, **({} if env_id == CELL else FAST))
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        env.reset(seed=0, options=options)


def test_vector_env_options_are_one_per_sub_env_as_the_single_env_takes_them():
    vec = gym.make_vec(CLUTTER, num_envs=3, vectorization_mode="vector_entry_point", **FAST)
    scene_seeds, task_seeds = [4, None, 6], [None, 11, 12]
    obs, infos = vec.reset(seed=20, options={"scene_seed": scene_seeds, "task_seed": task_seeds})
    for i in range(3):
        single = gym.make(CLUTTER, **FAST)
        options = {"scene_seed": scene_seeds[i], "task_seed": task_seeds[i]}
        single_obs, single_info = single.reset(seed=20 + i, options=options)
        np.testing.assert_array_equal(obs[i], single_obs)
        assert infos["scene_seed"][i] == single_info["scene_seed"]
        assert infos["_task_seed"][i] == ("task_seed" in single_info)
    with pytest.raises(ValueError, match="must hold 3 entries"):
        vec.reset(seed=0, options={"task_seed": [1, 2]})
    with pytest.raises(ValueError, match="unknown reset options"):
        vec.reset(seed=0, options={"seed": [1, 2, 3]})


def _play(env: gym.Env, policy, seed: int) -> tuple[list, float, dict]:
    obs, info = env.reset(seed=seed)
    steps, total, terminated = [], 0.0, False
    while not terminated:
        action, _ = policy(obs, info)
        obs, reward, terminated, _, step_info = env.step(action)
        steps.append((obs, reward, step_info))
        total += reward
        info = step_info
    return steps, total, info


@pytest.mark.parametrize("env_id", [CELL, CLUTTER, "IKBranch/IRB2600Screwing-v0"])
def test_optimal_return_is_the_oracles_and_changes_nothing_else(env_id):
    with_it = gym.make(env_id, optimal_return=True)
    without = gym.make(env_id)
    oracle = make_baseline("dp_oracle", with_it)
    random = np.random.default_rng(3)
    for seed in range(3):
        # The oracle's own plan replayed: its return, summed as the env sums, is the info's.
        steps, total, last = _play(with_it, lambda o, i: oracle.predict(
            o, action_masks=i["action_mask"]), seed)
        assert last["optimal_return"] == total
        assert all(info["optimal_return"] == total for _, _, info in steps)
        # Any masked policy does no better, and the option changes no observation or reward.
        actions = []

        def masked(o, info, actions=actions):
            actions.append(int(random.choice(np.flatnonzero(info["action_mask"]))))
            return actions[-1], None

        played, mine, _ = _play(with_it, masked, seed)
        assert mine <= total
        replay = iter(actions)
        plain, plain_total, _ = _play(without, lambda o, i, r=replay: (next(r), None), seed)
        assert plain_total == mine
        for (obs_a, r_a, info_a), (obs_b, r_b, info_b) in zip(played, plain, strict=True):
            np.testing.assert_array_equal(obs_a, obs_b)
            assert r_a == r_b
            assert {k: v for k, v in info_a.items() if k != "optimal_return"}.keys() == \
                info_b.keys()


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP],
                         ids=lambda m: m.name.lower())
def test_vector_env_reports_optimal_returns_as_its_single_envs(mode):
    kwargs = {**FAST, "optimal_return": True}
    native = gym.make_vec(CLUTTER, num_envs=3, vectorization_mode="vector_entry_point",
                          autoreset_mode=mode, **kwargs)
    sync = gym.make_vec(CLUTTER, num_envs=3, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kwargs)
    first = native.reset(seed=5)
    assert data_equivalence(first, sync.reset(seed=5), exact=True)
    assert first[1]["_optimal_return"].all()
    infos, rng, ends = first[1], np.random.default_rng(6), 0
    for _ in range(20):
        actions = (rng.random(infos["action_mask"].shape) * infos["action_mask"]).argmax(axis=1)
        step = native.step(actions)
        assert data_equivalence(step, sync.step(actions), exact=True)
        infos = step[4]
        ends += int(step[2].sum())
    assert ends >= 2
