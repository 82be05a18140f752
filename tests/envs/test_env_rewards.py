"""Rewards: the sum of the reported terms, what planners see through ``edge_rewards``, and
the paper's worked example."""

from __future__ import annotations

import itertools

import gymnasium as gym
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics.paper_example import PRINTED_MIN_TRAVEL_DEG
from tests.envs.env_cases import IDS, INFO_TERMS, make, rollout


def _check_episodes(base, records) -> None:
    """``_check_terms`` on every step of recorded episodes."""
    for record in records:
        if record[0] == "reset":
            history = []
            continue
        action, _, reward, terminated, truncated, info = record
        assert info["branch"] == action and not truncated
        history.append(info)
        _check_terms(base, info, reward, terminated, history)


def _check_terms(base, info, reward, terminated, history) -> None:
    total = 0.0
    for name in INFO_TERMS:  # the documented order: the sum is exact, not approximate
        total += info[name]
    assert reward == total
    assert info["reward_travel"] == -base.cost.travel_weight * info["travel"]
    assert info["reward_time"] == -base.cost.time_weight * info["time"]
    assert info["reward_collision"] == (-base.collision_penalty if info["collision"] else 0.0)
    assert info["reward_invalid"] == (-base.invalid_penalty if info["invalid"] else 0.0)
    n, w = base.task.n_waypoints, info["waypoint"]
    # Waypoints an early end leaves unvisited: an invalid branch never reaches its own.
    skipped = n - w if info["invalid"] else (n - 1 - w if terminated else 0)
    assert info["reward_unfinished"] == (-skipped * base.max_transition_cost if skipped else 0.0)
    assert terminated == (info["invalid"] or w == n - 1
                          or (info["collision"] and base.terminate_on_collision))
    if info["invalid"]:
        assert info["travel"] == 0.0 and not info["collision"]
    if terminated:
        clean = not any(step["collision"] or step["invalid"] for step in history)
        assert info["is_success"] == (w == n - 1 and clean)
    else:
        assert "is_success" not in info


@pytest.mark.parametrize("terminate_on_collision", [True, False])
@pytest.mark.parametrize("env_id", IDS)
def test_reward_is_the_sum_of_the_info_terms(env_id, terminate_on_collision):
    env = make(env_id, terminate_on_collision=terminate_on_collision, time_weight=0.5,
               n_waypoints=4)
    _check_episodes(env.unwrapped, rollout(env, seed=2, action_seed=3, episodes=3,
                                           p_unmasked=0.3))


@pytest.mark.parametrize(
    ("env_id", "kwargs", "term"),
    [
        ("IKBranch/ToolTransfer-v0", {"terminate_on_collision": False}, "collision"),
        ("IKBranch/ToolTransfer-v0", {}, "collision"),
        ("IKBranch/RodMechanism-v1", {}, "invalid"),
        ("IKBranch/Anthropomorphic-v1", {"terminate_on_collision": False}, "invalid"),
    ],
)
def test_rollouts_do_exercise_collisions_and_invalid_branches(env_id, kwargs, term):
    env = make(env_id, time_weight=0.5, **kwargs)
    records = rollout(env, seed=0, action_seed=0, episodes=8, p_unmasked=0.5)
    _check_episodes(env.unwrapped, records)
    infos = [record[-1] for record in records if record[0] != "reset"]
    assert any(info[term] for info in infos)
    if kwargs.get("terminate_on_collision") is False:  # the episode went on after a crash
        n = env.unwrapped.n_waypoints
        assert any(info["collision"] and info["waypoint"] < n - 1 for info in infos)


@pytest.mark.parametrize("env_id", IDS)
def test_edge_rewards_price_what_step_pays(env_id):
    kwargs = {"terminate_on_collision": False} if env_id.endswith("ToolTransfer-v0") else {}
    env = make(env_id, time_weight=0.3, **kwargs)
    base, rng = env.unwrapped, np.random.default_rng(7)
    for seed in range(3):
        env.reset(seed=seed)
        previous = None
        while base.index < base.task.n_waypoints:
            waypoint = base.index
            reward, terminal = base.edge_rewards(waypoint)
            assert reward.shape == terminal.shape == ((1 if waypoint == 0 else base.arm.n_branches),
                                                      base.arm.n_branches)
            row = 0 if waypoint == 0 else previous
            assert np.array_equal(base.q, base.task.start if waypoint == 0
                                  else base.candidates[waypoint - 1, row])
            action = int(rng.integers(base.arm.n_branches)) if rng.random() < 0.3 else int(
                rng.choice(np.flatnonzero(base.action_masks())))
            _, paid, terminated, _, _ = env.step(action)
            assert paid == reward[row, action] and terminated == terminal[row, action]
            previous = action
        if waypoint > 0:  # rows of invalid origins are NaN and terminal
            bad = ~base.valid[waypoint - 1]
            assert np.isnan(reward[bad]).all() and terminal[bad].all()


@pytest.fixture(scope="module")
def paper_empty():
    env = gym.make("IKBranch/ToolTransfer-v0", task="paper_transfer", scene="empty").unwrapped
    env.reset(seed=0)
    return env


def _pair_returns(env) -> np.ndarray:
    """(K, K) return of every action pair (a, b): a picks position 1's branch, b moves."""
    k = env.arm.n_branches
    returns = np.empty((k, k))
    for a, b in itertools.product(range(k), repeat=2):
        env.reset(seed=0)
        _, first, terminated, _, _ = env.step(a)
        returns[a, b] = first if terminated else first + env.step(b)[1]
    return returns


def test_paper_transfer_best_return_is_the_papers_minimum(paper_empty):
    returns = _pair_returns(paper_empty)
    best = returns.max()
    # The paper prints 275.15°: the least Σ|Δφ| to its rounding.
    assert round(np.degrees(-best), 2) == PRINTED_MIN_TRAVEL_DEG
    assert best == pytest.approx(-np.radians(PRINTED_MIN_TRAVEL_DEG), abs=np.radians(0.005))
    winners = {tuple(int(i) for i in pair) for pair in np.argwhere(returns == best)}
    assert winners == {(0, 0), (1, 1)}  # the paper's 1.1 → 2.1 and 1.2 → 2.2
    # The first step only picks the standing branch: no motion, no cost.
    reward0, _ = paper_empty.edge_rewards(0)
    assert np.all(reward0 == 0.0)
    reward1, _ = paper_empty.edge_rewards(1)
    assert np.array_equal(returns, reward0[0][:, None] + reward1)


def test_paper_transfer_recommended_pair_is_free_in_the_milling_cell():
    env = gym.make("IKBranch/ToolTransfer-v0", task="paper_transfer").unwrapped
    env.reset(seed=0)
    _, r0, terminated, _, info0 = env.step(0)
    assert not terminated and not info0["collision"]
    _, r1, terminated, _, info1 = env.step(0)
    assert terminated and info1["is_success"] and not info1["collision"]
    assert round(np.degrees(-(r0 + r1)), 2) == PRINTED_MIN_TRAVEL_DEG
