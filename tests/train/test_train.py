"""python -m train: config files, a real (tiny) training run, resume."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from sb3_contrib import MaskablePPO

import ikbranch_gym.envs as envs
from ikbranch_gym.train.hyperparams import ALGORITHMS, CONFIG, hyperparams_for, load_config
from ikbranch_gym.train.training import RunConfig, resolve

TINY = '{"n_steps": 64, "batch_size": 32, "n_epochs": 2, "eval_freq": 400, ' \
       '"n_eval_episodes": 2, "checkpoint_freq": 400}'
ENV = "IKBranch/ToolTransfer-v0"


def test_config_keys_are_exactly_the_registered_ids():
    assert set(load_config(CONFIG)) == set(envs.ENV_IDS)


@pytest.mark.parametrize("algo", ALGORITHMS)
def test_every_entry_resolves_for_every_algorithm(algo):
    for env_id in envs.ENV_IDS:
        params = hyperparams_for(env_id, algo)
        assert params["n_timesteps"] > 0 and params["policy"] in ("MlpPolicy", "BranchPolicy")
        assert not set(params) & set(ALGORITHMS)  # overrides merged, not left nested


def test_algorithm_overrides_apply_to_their_algorithm_only(tmp_path):
    path = tmp_path / "config.yml"
    path.write_text(f"{ENV}:\n  n_timesteps: 10\n  n_steps: 64\n"
                    "  maskable_ppo:\n    n_steps: 128\n")
    assert hyperparams_for(ENV, "ppo", path)["n_steps"] == 64
    assert hyperparams_for(ENV, "maskable_ppo", path)["n_steps"] == 128
    path.write_text(f"{ENV}:\n  n_timesteps: 10\n  dqn:\n    n_steps: 128\n")
    with pytest.raises(ValueError, match="unknown algorithm"):
        load_config(path)


def test_unknown_ids_are_errors_not_defaults(tmp_path):
    bad = tmp_path / "bad.yml"
    bad.write_text("IKBranch/Nope-v0:\n  n_timesteps: 10\n")
    with pytest.raises(ValueError, match="not registered env ids"):
        load_config(bad)
    partial = tmp_path / "partial.yml"
    partial.write_text(f"{ENV}:\n  n_timesteps: 10\n")
    with pytest.raises(ValueError, match="no entry for"):
        hyperparams_for("IKBranch/Cartesian-v1", "ppo", partial)
    with pytest.raises(ValueError, match="unknown algorithm"):
        hyperparams_for(ENV, "dqn")


def test_command_line_overrides_win():
    run = RunConfig(algo="ppo", env_id=ENV, seed=0, run_dir=Path("unused"), timesteps=123,
                    n_envs=1, env_kwargs={"lookahead": 1}, hyperparams={"learning_rate": 0.01})
    params = resolve(run)
    file_params = hyperparams_for(ENV, "ppo")
    assert params["n_timesteps"] == 123 != file_params["n_timesteps"]
    assert params["n_envs"] == 1 and params["learning_rate"] == 0.01
    assert params["env_kwargs"] == {"lookahead": 1}
    assert params["gamma"] == file_params["gamma"]


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "train", *args], capture_output=True, text=True, timeout=300,
        check=False,
    )


def test_training_run_writes_a_complete_run_directory_and_resumes(tmp_path):
    run_dir = tmp_path / "run"
    common = ["--algo", "maskable_ppo", "--env", ENV, "--seed", "3", "--n-envs", "2",
              "--run-dir", str(run_dir), "--hyperparams", TINY, "--no-progress"]
    first = run_cli(*common, "--timesteps", "1000")
    assert first.returncode == 0, first.stderr
    for name in ("model.zip", "config.yml", "command.txt", "versions.yml",
                 "checkpoints/latest.zip", "best/best_model.zip", "evaluations.npz"):
        assert (run_dir / name).exists(), name
    assert list((run_dir / "tb").iterdir()), "TensorBoard logs"
    # Checkpoints are written atomically: no temporary file of the writer is left behind.
    assert not list(run_dir.rglob(".*.tmp")), "checkpoints are written atomically"
    config = yaml.safe_load((run_dir / "config.yml").read_text())
    assert config["env_id"] == ENV and config["hyperparams"]["n_steps"] == 64
    assert "stable-baselines3" in yaml.safe_load((run_dir / "versions.yml").read_text())
    first_steps = MaskablePPO.load(run_dir / "model.zip").num_timesteps
    assert first_steps >= 1000
    with np.load(run_dir / "evaluations.npz") as log:
        first_log = {key: log[key] for key in log}
    assert first_log["timesteps"].tolist() == [400, 800]

    # A second start without --resume refuses to overwrite the run.
    refused = run_cli(*common, "--timesteps", "1000")
    assert refused.returncode != 0 and "--resume" in refused.stderr

    resumed = run_cli(*common, "--timesteps", "1600", "--resume")
    assert resumed.returncode == 0, resumed.stderr
    model = MaskablePPO.load(run_dir / "model.zip")
    assert model.num_timesteps >= 1600 > first_steps
    assert len((run_dir / "command.txt").read_text().splitlines()) == 2
    # The learning curve goes on from the first part's evaluations, which stay as they were.
    with np.load(run_dir / "evaluations.npz") as log:
        timesteps = log["timesteps"]
        assert timesteps[:2].tolist() == [400, 800] and len(timesteps) > 2
        assert (np.diff(timesteps) > 0).all() and timesteps[2] > first_steps
        # ... and on the same grid of steps as a run that never stopped.
        assert (timesteps % 400 == 0).all()
        for key, values in first_log.items():
            np.testing.assert_array_equal(log[key][:2], values)

    import gymnasium as gym

    env = gym.make(ENV)
    obs, _ = env.reset(seed=0)
    masks = env.unwrapped.action_masks()
    action, _ = model.predict(obs, action_masks=masks, deterministic=True)
    assert masks[int(action)]
    assert np.isfinite(obs).all()


def test_unknown_env_id_is_rejected_by_the_cli(tmp_path):
    result = run_cli("--algo", "ppo", "--env", "IKBranch/Nope-v0", "--run-dir", str(tmp_path))
    assert result.returncode != 0 and "unknown env id" in result.stderr


@pytest.mark.parametrize(("algo", "policy_name"),
                         [("ppo", "BranchPolicy"), ("maskable_ppo", "MaskableBranchPolicy")])
def test_branch_policy_from_a_config_name(algo, policy_name, tmp_path):
    from ikbranch_gym.train.training import train

    run = RunConfig(
        algo=algo, env_id="IKBranch/ToolTransfer-v0", seed=0, run_dir=tmp_path / algo,
        timesteps=64, n_envs=1, progress_bar=False,
        hyperparams={"policy": "BranchPolicy", "policy_kwargs": {}, "n_steps": 32, "batch_size": 16,
                     "eval_freq": 10_000, "checkpoint_freq": 10_000},
    )
    model = train(run)
    assert type(model.policy).__name__ == policy_name
    assert (tmp_path / algo / "model.zip").exists()
