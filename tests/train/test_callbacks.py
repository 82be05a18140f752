"""Checkpoints (train.callbacks) are written atomically: every file loads, a save that fails
half-way leaves the previous checkpoint as it was, and no temporary file stays behind."""

from __future__ import annotations

import stat

import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecNormalize

from ikbranch_gym.train.callbacks import LATEST, REWARD_STATS, AtomicCheckpointCallback


@pytest.fixture
def callback(tmp_path):
    env = VecNormalize(make_vec_env("CartPole-v1", n_envs=1, seed=0))
    model = PPO("MlpPolicy", env, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu")
    checkpoint = AtomicCheckpointCallback(save_freq=1, save_dir=tmp_path / "checkpoints")
    checkpoint.init_callback(model)
    checkpoint.num_timesteps = 16
    yield checkpoint
    env.close()


def test_a_checkpoint_is_every_file_whole(callback):
    path = callback.save()
    directory = callback.save_dir
    assert path == directory / "ckpt_16.zip"
    assert sorted(p.name for p in directory.iterdir()) == ["ckpt_16.zip", LATEST, REWARD_STATS]
    saved = PPO.load(directory / LATEST, device="cpu")
    for name, value in callback.model.policy.state_dict().items():
        assert np.array_equal(saved.policy.state_dict()[name].numpy(), value.numpy()), name
    assert (directory / "ckpt_16.zip").read_bytes() == (directory / LATEST).read_bytes()
    stats = VecNormalize.load(str(directory / REWARD_STATS), callback.model.get_env())
    assert np.array_equal(stats.ret_rms.var, callback.model.get_env().ret_rms.var)
    # A new file's permissions are an ordinary open's (the umask applies).
    ordinary = directory / "ordinary"
    ordinary.write_bytes(b"")
    assert stat.S_IMODE((directory / LATEST).stat().st_mode) == stat.S_IMODE(
        ordinary.stat().st_mode)


def test_a_save_failing_half_way_keeps_the_previous_checkpoint(callback, monkeypatch):
    callback.save()
    directory = callback.save_dir
    before = {p.name: p.read_bytes() for p in directory.iterdir()}
    save = callback.model.save

    def crash(target, *args, **kwargs):
        save(target, *args, **kwargs)
        if hasattr(target, "truncate"):  # a stream: half of it, then the process "dies"
            target.truncate(100)
        else:
            with open(target, "r+b") as stream:
                stream.truncate(100)
        raise KeyboardInterrupt

    monkeypatch.setattr(callback.model, "save", crash)
    callback.num_timesteps = 32
    with pytest.raises(KeyboardInterrupt):
        callback.save()
    assert {p.name: p.read_bytes() for p in directory.iterdir()} == before
    PPO.load(directory / LATEST, device="cpu")  # still loads
