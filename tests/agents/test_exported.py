"""A model's actor exported for a controller (``agents.exported``, ``ikbranch export``):
the model's own decisions from numpy alone, and clear errors for what it cannot use."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from sb3_contrib import MaskablePPO
from stable_baselines3 import PPO
from torch import nn

import ikbranch_gym.envs  # noqa: F401  (registers the ids)
from ikbranch_gym.agents.base import action_mask
from ikbranch_gym.agents.evaluation import build_policy, evaluate
from ikbranch_gym.agents.exported import ExportedPolicy, export_policy, exported_arrays
from ikbranch_gym.agents.sb3 import SB3Policy
from ikbranch_gym.envs.seeds import TEST_SEED, held_out
from ikbranch_gym.train import export as export_cli
from ikbranch_gym.train.export import model_logits

#: Committed models, one of each kind an export must handle: (env id, model).
MODELS = [
    # BranchPolicy, compact observation with two later slots summarised, masks
    ("IKBranch/UR5e-v1", "models/UR5e-v1/bc_maskable_ppo.zip"),
    # BranchPolicy without masks
    ("IKBranch/UR5e-v1", "models/UR5e-v1/ppo.zip"),
    # BranchPolicy, ladder observation (slot 1's K × K travel per branch)
    ("IKBranch/Anthropomorphic-v1", "models/Anthropomorphic-v1/maskable_ppo.zip"),
    # SB3's MlpPolicy, with and without masks
    ("IKBranch/Cartesian-v3", "models/Cartesian-v3/maskable_ppo.zip"),
    ("IKBranch/Cartesian-v3", "models/Cartesian-v3/ppo.zip"),
    # BranchPolicy reading the free travel of several moves per branch
    ("IKBranch/Anthropomorphic-v4", "models/Anthropomorphic-v4/maskable_ppo.zip"),
]
EPISODES = 4


def _played(env_id: str, model: SB3Policy) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Observations, masks and the model's deterministic actions on held-out tasks."""
    env = gym.make(env_id, **held_out(env_id))
    observations, masks, actions = [], [], []
    for e in range(EPISODES):
        observation, info = env.reset(seed=TEST_SEED + e)
        done = False
        while not done:
            mask = action_mask(env, info)
            action, _ = model.predict(observation, deterministic=True, action_masks=mask)
            observations.append(observation)
            masks.append(mask)
            actions.append(int(action))
            observation, _, terminated, truncated, info = env.step(int(action))
            done = terminated or truncated
    env.close()
    return np.array(observations), np.array(masks), np.array(actions)


@pytest.mark.parametrize(("env_id", "path"), MODELS, ids=[m for _, m in MODELS])
def test_the_exported_actor_decides_as_the_model(env_id, path, tmp_path):
    env = gym.make(env_id)
    model = SB3Policy.load(path, env)
    observations, masks, actions = _played(env_id, model)
    file = export_policy(model.model, tmp_path / "actor.npz")
    actor = ExportedPolicy.load(file, env)
    assert actor.maskable == model.maskable
    decided = actor.decide_many(observations, masks if actor.maskable else None)
    np.testing.assert_array_equal(decided, actions)
    for i in range(len(observations)):  # one at a time, as a controller asks
        assert actor.decide(observations[i], masks[i] if actor.maskable else None) == actions[i]
    # The logits are torch's up to float32 rounding of another order of operations.
    logits, expected = actor.logits(observations), model_logits(model, observations)
    assert logits.dtype == np.float32
    np.testing.assert_allclose(logits, expected, rtol=0, atol=2e-5 * max(1.0, np.abs(
        expected).max()))
    # The file holds exactly the arrays export computed.
    again = ExportedPolicy(exported_arrays(model.model))
    np.testing.assert_array_equal(again.logits(observations), logits)


def test_an_unmasked_model_may_choose_a_branch_the_mask_forbids():
    # PPO was trained without masks: its exported actor, like SB3's predict, takes the
    # highest logit over every branch and ignores a mask.
    env_id, path = MODELS[1]
    model = SB3Policy.load(path, gym.make(env_id))
    observations, masks, actions = _played(env_id, model)
    actor = ExportedPolicy(exported_arrays(model.model))
    np.testing.assert_array_equal(actor.decide_many(observations, ~masks), actions)


def test_an_exported_file_is_evaluated_like_its_model(tmp_path):
    env_id, path = MODELS[3]
    file = tmp_path / "cartesian.npz"
    assert export_cli.main([path, "--env", env_id, "--out", str(file), "--episodes", "3"]) == 0
    name, policy = build_policy(str(file), gym.make(env_id), TEST_SEED)
    assert name == str(file.with_suffix("")) and isinstance(policy, ExportedPolicy)
    results = evaluate(env_id, [path, str(file)], 3, TEST_SEED, held_out(env_id))
    rows = results["policies"]
    exported, original = rows[str(file.with_suffix(""))], rows[path.removesuffix(".zip")]
    assert exported["returns"] == original["returns"]
    assert exported["successes"] == original["successes"]


def test_the_export_command_writes_nothing_when_a_decision_differs(tmp_path, monkeypatch,
                                                                   capsys):
    env_id, path = MODELS[3]

    def other(self, observation, state=None, episode_start=None, deterministic=True,
              action_masks=None):
        return np.int64(-1), state

    monkeypatch.setattr(ExportedPolicy, "predict", other)
    file = tmp_path / "actor.npz"
    assert export_cli.main([path, "--env", env_id, "--out", str(file), "--episodes", "1"]) == 1
    assert not file.exists()
    assert "differ from the model's" in capsys.readouterr().out


def test_deciding_needs_numpy_alone(tmp_path):
    env_id, path = MODELS[0]
    file = export_policy(SB3Policy.load(path, gym.make(env_id)).model, tmp_path / "a.npz")
    observation = gym.make(env_id).reset(seed=0)[0]
    np.save(tmp_path / "obs.npy", observation)
    code = (
        "import sys, numpy as np\n"
        "from ikbranch_gym.agents.exported import ExportedPolicy\n"
        f"actor = ExportedPolicy.load({str(file)!r})\n"
        f"obs = np.load({str(tmp_path / 'obs.npy')!r})\n"
        "print(actor.decide(obs, np.ones(actor.n_branches, bool)))\n"
        "assert 'torch' not in sys.modules and 'stable_baselines3' not in sys.modules\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    assert 0 <= int(done.stdout) < 256


# ------------------------------------------------------------------------- bad input
@pytest.fixture(scope="module")
def cartesian() -> tuple[gym.Env, ExportedPolicy, dict]:
    env_id, path = MODELS[3]
    env = gym.make(env_id)
    arrays = exported_arrays(SB3Policy.load(path, env).model)
    return env, ExportedPolicy(arrays, env=env), arrays


def test_files_that_are_not_exported_policies_are_named(tmp_path, cartesian):
    _, _, arrays = cartesian
    text = tmp_path / "notes.npz"
    text.write_text("not an archive")
    with pytest.raises(ValueError, match=r"notes\.npz: not an exported policy"):
        ExportedPolicy.load(text)
    plain = tmp_path / "plain.npz"
    np.savez(plain, weights=np.zeros(3))
    with pytest.raises(ValueError, match=r"plain\.npz: not an exported policy"):
        ExportedPolicy.load(plain)
    newer = tmp_path / "newer.npz"
    np.savez(newer, **{**arrays, "version": np.array(2)})
    with pytest.raises(ValueError, match=r"newer\.npz: exported policy version 2"):
        ExportedPolicy.load(newer)
    unversioned = tmp_path / "unversioned.npz"
    np.savez(unversioned, **{k: v for k, v in arrays.items() if k != "version"})
    with pytest.raises(ValueError, match="exported policy version missing"):
        ExportedPolicy.load(unversioned)
    partial = tmp_path / "partial.npz"
    np.savez(partial, **{k: v for k, v in arrays.items() if k != "action_bias"})
    with pytest.raises(ValueError, match=r"partial\.npz: exported policy without action_bias"):
        ExportedPolicy.load(partial)
    elu = tmp_path / "elu.npz"
    np.savez(elu, **{**arrays, "activation": np.array("ELU")})
    with pytest.raises(ValueError, match=r"elu\.npz: activation 'ELU'; this package reads"):
        ExportedPolicy.load(elu)
    with pytest.raises(ValueError, match=r"\.npz file"):
        export_policy(SB3Policy.load(MODELS[3][1]).model, tmp_path / "actor.zip")


def test_bad_observations_and_masks_are_refused(cartesian):
    env, actor, arrays = cartesian
    observation = env.reset(seed=1)[0]
    k = actor.n_branches
    with pytest.raises(ValueError, match=r"observations of shape \(1, 3\)"):
        actor.decide(np.zeros(3, np.float32), np.ones(k, bool))
    with pytest.raises(ValueError, match="NaN"):
        actor.decide(np.full_like(observation, np.nan), np.ones(k, bool))
    with pytest.raises(ValueError, match="trained with action masks"):
        actor.decide(observation)
    with pytest.raises(ValueError, match="without a valid branch"):
        actor.decide(observation, np.zeros(k, bool))
    with pytest.raises(ValueError, match="masks of shape"):
        actor.decide_many(observation[None], np.ones((1, k + 1), bool))
    with pytest.raises(ValueError, match="deterministically"):
        actor.predict(observation, deterministic=False)
    with pytest.raises(ValueError, match="observations of size"):
        ExportedPolicy(arrays, env=gym.make("IKBranch/UR5e-v1"))


def test_an_actor_it_cannot_express_is_refused():
    env = gym.make("IKBranch/Cartesian-v3")
    model = PPO("MlpPolicy", env, policy_kwargs={"activation_fn": nn.ELU}, n_steps=8,
                batch_size=8, device="cpu")
    with pytest.raises(ValueError, match=r"cannot export activations \['ELU'\]"):
        exported_arrays(model)
    relu = MaskablePPO("MlpPolicy", env, policy_kwargs={"activation_fn": nn.ReLU},
                       n_steps=8, batch_size=8, device="cpu")
    observation, info = env.reset(seed=2)
    actor = ExportedPolicy(exported_arrays(relu), env=env)
    expected, _ = relu.predict(observation, deterministic=True,
                               action_masks=info["action_mask"])
    assert actor.decide(observation, info["action_mask"]) == int(expected)
