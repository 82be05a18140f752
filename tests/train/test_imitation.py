"""bc_maskable_ppo: the oracle's demonstrations, the clone, the run that starts from it."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.running_mean_std import RunningMeanStd

from ikbranch_gym.agents import DPOracle
from ikbranch_gym.envs.seeds import IMITATION_OFFSET
from ikbranch_gym.train import imitation
from ikbranch_gym.train.hyperparams import IMITATION_KEYS, hyperparams_for
from ikbranch_gym.train.training import RunConfig, train

ENV = "IKBranch/Anthropomorphic-v3"


@pytest.fixture(scope="module")
def demos() -> imitation.Demonstrations:
    env = gym.make(ENV)
    try:
        return imitation.oracle_demonstrations(env, 12, seed=500)
    finally:
        env.close()


def test_demonstrations_are_the_oracles_plans(demos):
    # Each episode is the oracle's plan, replayed: its choices and its planned return.
    env = gym.make(ENV)
    oracle = DPOracle(env)
    starts = np.flatnonzero(np.concatenate([[True], demos.ends[:-1]]))
    assert len(starts) == demos.episodes == 12 and demos.ends[-1]
    for e, start in enumerate(starts):
        env.reset(seed=500 + e)
        oracle.on_episode()
        stop = start + len(oracle.plan)
        assert demos.ends[stop - 1] and not demos.ends[start : stop - 1].any()
        np.testing.assert_array_equal(demos.actions[start:stop], oracle.plan)
        assert demos.rewards[start:stop].sum() == pytest.approx(oracle.planned_return,
                                                               abs=1e-9)
    assert demos.masks[np.arange(len(demos)), demos.actions].all()
    assert np.isfinite(demos.observations).all()
    env.close()


def test_demonstrations_are_reproducible(demos):
    env = gym.make(ENV)
    again = imitation.oracle_demonstrations(env, 12, seed=500)
    np.testing.assert_array_equal(again.observations, demos.observations)
    np.testing.assert_array_equal(again.actions, demos.actions)
    with pytest.raises(ValueError, match="imitation_episodes"):
        imitation.oracle_demonstrations(env, 0, seed=500)


def test_discounted_returns_restart_at_each_episode():
    rewards = np.array([1.0, 2.0, 4.0, 8.0, 16.0])
    ends = np.array([False, True, False, False, True])
    out = imitation.discounted_returns(rewards, ends, 0.5)
    np.testing.assert_allclose(out, [1 + 0.5 * 2, 2, 4 + 0.5 * 8 + 0.25 * 16, 8 + 0.5 * 16, 16])


def test_reward_scale_follows_vecnormalize():
    # VecNormalize keeps a running discounted sum of rewards, reset at episode ends, and
    # tracks the variance of its values: so must the seeding.
    rewards = np.array([-1.0, -3.0, -2.0, -5.0, -0.5, -4.0])
    ends = np.array([False, False, True, False, False, True])
    demos = imitation.Demonstrations(np.zeros((6, 1), np.float32), np.ones((6, 1), bool),
                                     np.zeros(6, np.int64), rewards, ends, episodes=2)
    stats = RunningMeanStd(shape=())
    imitation.seed_reward_scale(stats, demos, 0.9)
    sums = [-1.0, -1.0 * 0.9 - 3.0, (-1.0 * 0.9 - 3.0) * 0.9 - 2.0, -5.0, -5.0 * 0.9 - 0.5,
            (-5.0 * 0.9 - 0.5) * 0.9 - 4.0]
    assert stats.mean == pytest.approx(np.mean(sums), rel=1e-3)
    assert stats.var == pytest.approx(np.var(sums), rel=1e-3)


def test_run_starts_from_the_clone_of_the_oracle(tmp_path):
    run = RunConfig(
        algo="bc_maskable_ppo", env_id=ENV, seed=2, run_dir=tmp_path / "run", timesteps=64,
        n_envs=1, progress_bar=False,
        hyperparams={"n_steps": 64, "batch_size": 32, "n_epochs": 1, "learning_rate": 0.0,
                     "eval_freq": 10_000, "checkpoint_freq": 10_000,
                     "imitation_episodes": 30, "imitation_epochs": 150},
    )
    model = train(run)
    record = json.loads((tmp_path / "run" / imitation.RECORD).read_text())
    assert record["episodes"] == 30 and record["task_seeds"] == [
        2 + IMITATION_OFFSET, 2 + IMITATION_OFFSET + 30]
    assert record["agreement"] > 0.9 and record["reward_scale"] > 1.0
    # PPO did not move the policy (learning rate 0): the model takes the oracle's choices
    # on the demonstrated decisions as often as the record says.
    env = gym.make(ENV)
    demos = imitation.oracle_demonstrations(env, 30, seed=2 + IMITATION_OFFSET)
    actions, _ = model.predict(demos.observations, action_masks=demos.masks,
                               deterministic=True)
    assert np.mean(actions == demos.actions) == pytest.approx(record["agreement"])
    assert demos.masks[np.arange(len(demos)), actions].all()


def test_every_id_configures_the_imitation_phase():
    import ikbranch_gym.envs as envs

    for env_id in envs.ENV_IDS:
        params = hyperparams_for(env_id, "bc_maskable_ppo")
        assert set(IMITATION_KEYS) <= set(params)
        assert not set(IMITATION_KEYS) & set(hyperparams_for(env_id, "maskable_ppo"))


def test_bad_imitation_settings_are_errors(tmp_path):
    env = gym.make(ENV)
    with pytest.raises(ValueError, match="needs imitation_epochs"):
        imitation.warm_start(None, env, {"imitation_episodes": 1}, 0, None, tmp_path)
    run = RunConfig(algo="bc_maskable_ppo", env_id=ENV, seed=0, run_dir=tmp_path / "bad",
                    timesteps=32, n_envs=1, progress_bar=False,
                    hyperparams={"n_steps": 32, "batch_size": 16, "imitation_episodes": 1,
                                 "imitation_batch_size": 0})
    with pytest.raises(ValueError, match="imitation_batch_size must be a positive integer"):
        train(run)
