"""The per-branch policy: equivariance, saving/loading under the right algorithm, training."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from sb3_contrib import MaskablePPO
from stable_baselines3 import PPO

import ikbranch_gym.envs  # noqa: F401  (registers the ids)
from ikbranch_gym.agents.branch_policy import (
    BranchFeatures,
    BranchPolicy,
    MaskableBranchPolicy,
    branch_policy_kwargs,
)
from ikbranch_gym.agents.evaluation import run_episode
from ikbranch_gym.agents.sb3 import SB3Policy, model_class


def _permuted(obs: np.ndarray, layout: dict, k: int, dof: int, order: np.ndarray) -> np.ndarray:
    """The observation with the next waypoint's branches listed in ``order``."""
    out = obs.copy()

    def block(name, width):
        start, stop = layout[name]
        return slice(start, stop), width

    for name, width in (("slot0/candidates", dof), ("slot0/valid", 1),
                        ("slot0/endpoint_collision", 1), ("slot0/travel", 1),
                        ("slot0/path_collision", 1), ("slot1/travel", k),
                        ("slot0/travel_out", 1), ("slot0/free_travel_out", 1),
                        ("slot0/free_travel_onward", 1)):
        if name not in layout:
            continue
        where, width = block(name, width)
        out[where] = obs[where].reshape(k, width)[order].ravel()
    return out


@pytest.mark.parametrize(("observation", "onward_moves"),
                         [("ladder", 1), ("compact", 1), ("compact", 3)])
def test_branch_scores_follow_the_branches_not_their_order(observation, onward_moves):
    env = gym.make("IKBranch/ToolTransfer-v0", observation=observation,
                   onward_moves=onward_moves)
    obs, _ = env.reset(seed=3)
    base = env.unwrapped
    k, dof = base.arm.n_branches, base.arm.dof
    kwargs = branch_policy_kwargs(env)["features_extractor_kwargs"]
    torch.manual_seed(0)
    features = BranchFeatures(env.observation_space, **kwargs)
    order = np.random.default_rng(0).permutation(k)
    with torch.no_grad():
        plain = features(torch.as_tensor(obs[None]))
        permuted = features(torch.as_tensor(_permuted(obs, base.observation_layout, k, dof,
                                                      order)[None]))
    np.testing.assert_allclose(permuted[0, :k], plain[0, :k][order], atol=1e-6)
    np.testing.assert_allclose(permuted[0, k:], plain[0, k:], atol=1e-6)  # pooled: invariant
    assert plain[0, :k].std() > 0  # the branches really get different scores
    onward = base.observation_layout.get("slot0/free_travel_onward")
    assert (onward is not None) == (onward_moves > 1)
    if onward is not None:  # each branch reads its own several-move onward travel
        np.testing.assert_array_equal(features.own[:, -1].numpy(), np.arange(*onward))


@pytest.mark.parametrize("observation", ["ladder", "compact"])
@pytest.mark.parametrize(("algorithm", "policy"),
                         [(PPO, BranchPolicy), (MaskablePPO, MaskableBranchPolicy)])
def test_saved_branch_models_load_under_their_algorithm(algorithm, policy, observation,
                                                       tmp_path):
    env = gym.make("IKBranch/RodMechanism-v1", n_waypoints=3, observation=observation)
    model = algorithm(policy, env, n_steps=32, batch_size=16, n_epochs=1, seed=0,
                      policy_kwargs=branch_policy_kwargs(env))
    model.learn(64)
    model.save(tmp_path / "model.zip")
    assert model_class(tmp_path / "model.zip") is algorithm
    loaded = SB3Policy.load(tmp_path / "model.zip", env)
    assert loaded.maskable == (algorithm is MaskablePPO)
    obs, _ = env.reset(seed=1)
    expected, _ = model.predict(obs, deterministic=True,
                                **({"action_masks": env.unwrapped.action_masks()}
                                   if algorithm is MaskablePPO else {}))
    action, _ = loaded.predict(obs, action_masks=env.unwrapped.action_masks())
    assert int(action) == int(expected)
    # A whole episode: the loaded policy acts as the trained model at every step.
    episode = run_episode(loaded, env, 5)
    obs, _ = env.reset(seed=5)
    done, steps = False, 0
    while not done:
        masks = env.unwrapped.action_masks()
        expected, _ = model.predict(obs, deterministic=True,
                                    **({"action_masks": masks} if algorithm is MaskablePPO
                                       else {}))
        action, _ = loaded.predict(obs, action_masks=masks)
        assert int(action) == int(expected)
        obs, _, done, _, _ = env.step(int(action))
        steps += 1
    assert steps == episode.steps


def test_branch_policy_needs_its_extractor_and_an_empty_actor():
    env = gym.make("IKBranch/RodMechanism-v1")
    with pytest.raises(ValueError, match="BranchFeatures"):
        PPO(BranchPolicy, env, policy_kwargs={"net_arch": {"pi": [], "vf": [8]}})
    with pytest.raises(ValueError, match="empty actor"):
        PPO(BranchPolicy, env, policy_kwargs=branch_policy_kwargs(
            env, net_arch={"pi": [8], "vf": [8]}))


@pytest.mark.parametrize("env_id", ["IKBranch/Anthropomorphic-v2", "IKBranch/UR5e-v0"])
def test_a_new_branch_policy_explores_every_valid_branch_alike(env_id):
    # The scores are the logits: initialised like SB3's action head (gain 0.01), the first
    # policy is near uniform over the valid branches, for K = 8 and for UR5e's K = 256.
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    masks = env.unwrapped.action_masks()
    model = MaskablePPO(MaskableBranchPolicy, env, seed=0, n_steps=64, batch_size=32,
                        policy_kwargs=branch_policy_kwargs(env))
    with torch.no_grad():
        tensor, _ = model.policy.obs_to_tensor(obs)
        distribution = model.policy.get_distribution(tensor, action_masks=masks)
        probs = distribution.distribution.probs[0].numpy()
    assert env.action_space.n == len(masks) and masks.sum() >= 2
    assert probs[~masks].max(initial=0.0) == 0.0
    valid = probs[masks]
    assert valid.max() / valid.min() < 1.1, (valid.min(), valid.max())
