"""SB3's view of the native vector env is the DummyVecEnv of Monitor-wrapped single envs
that ``make_vec_env`` builds, and a learner trained on either is the same learner."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from sb3_contrib.common.maskable.utils import get_action_masks
from stable_baselines3.common.env_util import make_vec_env

import ikbranch_gym.envs  # noqa: F401
from ikbranch_gym.train.training import RunConfig, train
from ikbranch_gym.train.vec_env import NativeVecEnv, make_native_vec_env


def _same(a, b) -> bool:
    return np.array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.parametrize("env_id", ["IKBranch/Cartesian-v2", "IKBranch/ToolTransfer-v1",
                                    "IKBranch/KukaKR6-v0", "IKBranch/DualRRRPPP-v1"])
def test_native_vec_env_is_dummy_vec_env_of_monitored_envs(env_id):
    n = 3
    reference = make_vec_env(lambda: gym.make(env_id, n_waypoints=3), n_envs=n, seed=7)
    native = make_native_vec_env(env_id, n, {"n_waypoints": 3}, seed=7)
    assert _same(reference.reset(), native.reset())
    rng = np.random.default_rng(8)
    episodes = 0
    for _ in range(40):
        masks = get_action_masks(native)
        assert _same(masks, get_action_masks(reference))
        actions = (rng.random(masks.shape) * masks).argmax(axis=1)
        (obs, rewards, dones, infos) = native.step(actions)
        (obs_r, rewards_r, dones_r, infos_r) = reference.step(actions)
        assert _same(obs, obs_r) and _same(dones, dones_r)
        assert rewards.dtype == rewards_r.dtype and _same(rewards, rewards_r)
        for i, (info, expected) in enumerate(zip(infos, infos_r, strict=True)):
            assert info.keys() == expected.keys()
            for key, value in expected.items():
                if key == "episode":  # Monitor's record: its time is the wall clock's
                    assert (info[key]["r"], info[key]["l"]) == (value["r"], value["l"])
                    episodes += 1
                else:
                    assert _same(info[key], value), key
            if dones[i]:
                assert native.reset_infos[i].keys() == reference.reset_infos[i].keys()
    assert episodes >= 3


def test_training_on_either_gives_the_same_learner(tmp_path):
    # The learner sees identical data: MaskablePPO's parameters after training, its
    # held-out evaluations and its best model agree bit for bit.
    # The native env's two sub-envs stepped in two threads too.
    models = {}
    for name, kind, threads in (("native", "native", 1), ("threads", "native", 2),
                                ("dummy", "dummy", 1)):
        run = RunConfig(algo="maskable_ppo", env_id="IKBranch/Cartesian-v2", seed=0,
                        run_dir=tmp_path / name, timesteps=1024, progress_bar=False,
                        vec_env=kind, env_threads=threads,
                        hyperparams={"n_steps": 256, "batch_size": 128, "eval_freq": 256,
                                     "n_eval_episodes": 3})
        models[name] = train(run)
    dummy = list(models["dummy"].policy.parameters())
    for name in ("native", "threads"):
        assert all(np.array_equal(a.detach().numpy(), b.detach().numpy())
                   for a, b in zip(models[name].policy.parameters(), dummy, strict=True))
        np.testing.assert_array_equal(np.load(tmp_path / name / "evaluations.npz")["results"],
                                      np.load(tmp_path / "dummy" / "evaluations.npz")["results"])
        assert (tmp_path / name / "best" / "best.json").read_text() == (
            tmp_path / "dummy" / "best" / "best.json").read_text()


def test_the_adapter_wants_a_same_step_vector_env():
    venv = gym.make_vec("IKBranch/Cartesian-v2", num_envs=2,
                        vectorization_mode="vector_entry_point")  # next-step by default
    with pytest.raises(ValueError, match="same-step"):
        NativeVecEnv(venv)
    sync = gym.make_vec("IKBranch/Cartesian-v2", num_envs=2, vectorization_mode="sync")
    with pytest.raises(TypeError, match="IKBranchVectorEnv"):
        NativeVecEnv(sync)
