"""The rule baselines, the paper's worked example, masks and the predict interface."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs  # noqa: F401
from ikbranch_gym.agents import BASELINES, FixedBranch, make_baseline
from ikbranch_gym.envs.kinematics.paper_example import PRINTED_MIN_TRAVEL_DEG

PAPER_PAIRS = ([0, 0], [1, 1])  # 1.1 -> 2.1 or 1.2 -> 2.2


@pytest.mark.parametrize("name", ["paper_pair_rule", "dp_oracle"])
def test_paper_transfer_gives_the_papers_pair_and_travel(name):
    env = gym.make("IKBranch/ToolTransfer-v0", scene="empty", task="paper_transfer")
    policy = make_baseline(name, env)
    obs, _ = env.reset(seed=0)
    actions, travel, total, done = [], 0.0, 0.0, False
    while not done:
        action, _ = policy.predict(obs)
        obs, reward, done, _, info = env.step(action)
        actions.append(int(action))
        travel += info["travel"]
        total += reward
    assert actions in PAPER_PAIRS
    assert round(float(np.degrees(travel)), 2) == PRINTED_MIN_TRAVEL_DEG
    assert total == pytest.approx(-travel, abs=1e-12)  # empty scene: travel is the only cost


@pytest.mark.parametrize("name", sorted(BASELINES))
@pytest.mark.parametrize("env_id", ["IKBranch/RodMechanism-v1", "IKBranch/Spherical-v1"])
def test_baselines_never_pick_a_masked_branch(name, env_id):
    env = gym.make(env_id, n_waypoints=6)
    policy = make_baseline(name, env)
    masked_seen = 0
    for seed in range(4):
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            mask = env.unwrapped.action_masks()
            masked_seen += int((~mask).sum())
            action, _ = policy.predict(obs, action_masks=mask)
            assert mask[int(action)]
            obs, _, done, _, info = env.step(action)
            assert not info["invalid"]
    if env_id == "IKBranch/RodMechanism-v1":
        assert masked_seen > 0  # the rod's tasks do mask branches: the check has teeth


@pytest.mark.parametrize("name", sorted(BASELINES))
def test_a_stricter_caller_mask_is_honoured(name):
    env = gym.make("IKBranch/ToolTransfer-v0", n_waypoints=3)
    policy = make_baseline(name, env)
    obs, _ = env.reset(seed=0)
    only = np.zeros(8, dtype=bool)
    only[5] = True
    action, _ = policy.predict(obs, action_masks=only)
    assert int(action) == 5


def test_predict_follows_sb3_shapes():
    env = gym.make("IKBranch/RodMechanism-v1", n_waypoints=3)
    policy = make_baseline("paper_rule", env)
    obs, _ = env.reset(seed=0)
    action, state = policy.predict(obs, state="kept")
    assert action.shape == () and state == "kept"
    action, _ = policy.predict(obs[None], episode_start=np.array([True]))
    assert action.shape == (1,)
    with pytest.raises(ValueError, match="batch"):
        policy.predict(np.stack([obs, obs]))


def test_paper_rule_takes_the_least_travel():
    env = gym.make("IKBranch/ToolTransfer-v0", n_waypoints=4)
    policy = make_baseline("paper_rule", env)
    obs, _ = env.reset(seed=2)
    base = env.unwrapped
    while True:
        action, _ = policy.predict(obs)
        travel = base.cost.travel(base.q, base.candidates[base.index])
        assert travel[int(action)] == pytest.approx(np.nanmin(travel), abs=1e-9)
        obs, _, done, _, _ = env.step(action)
        if done:
            break


def test_fixed_takes_its_branch_then_the_nearest_label():
    env = gym.make("IKBranch/ToolTransfer-v0", n_waypoints=3)
    env.reset(seed=0)
    labels = env.unwrapped.arm.branch_labels
    fixed = FixedBranch(env, branch="back/elbow-up/wrist+")
    assert fixed.branch == 4 and FixedBranch(env, branch="4").branch == 4
    everything = np.ones(8, dtype=bool)
    assert fixed.choose(0, everything) == 4
    # Without branch 4, one flag flipped: wrist (5) or elbow (6) before shoulder (0).
    assert fixed.choose(0, everything & (np.arange(8) != 4)) == 5
    assert labels[fixed.choose(0, np.isin(np.arange(8), [0, 6]))] == "back/elbow-down/wrist+"
    for bad in (8, -1, "sideways"):
        with pytest.raises(ValueError, match="branch"):
            FixedBranch(env, branch=bad)


def test_random_is_reproducible_under_its_seed_and_only_under_it():
    # Every branch of this task is valid and a collision does not end the episode: six
    # choices among eight, so two seeds agreeing everywhere would be a defect, not luck.
    env = gym.make("IKBranch/ToolTransfer-v0", n_waypoints=6, terminate_on_collision=False)

    def actions(seed):
        policy = make_baseline("random", env, seed=seed)
        obs, _ = env.reset(seed=0)
        out, done = [], False
        while not done:
            action, _ = policy.predict(obs)
            out.append(int(action))
            obs, _, done, _, _ = env.step(action)
        return out

    # The task is the same (reset(seed=0)) every time: only the policy's seed differs.
    first = actions(3)
    assert env.unwrapped.valid.all()
    assert actions(3) == first
    assert actions(4) != first


def test_unknown_baseline_is_a_value_error():
    env = gym.make("IKBranch/RodMechanism-v1")
    with pytest.raises(ValueError, match="unknown baseline"):
        make_baseline("genius", env)
