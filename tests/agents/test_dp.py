"""The DP oracle against brute force, against the env's own bookkeeping, and its horizon."""

from __future__ import annotations

import itertools

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs as envs
from ikbranch_gym.agents import DPOracle, RecedingDP, ladder_q_tables, make_baseline
from tests.agents.brute_force import brute_force

#: (env id, kwargs, seeds): arms with 1–8 branches, invalid branches (rod), terminal
#: collisions (spherical, rod, milling cell), collisions that do not end the episode, a
#: time term, and a two-arm system whose arms can hit each other.
CASES = [
    ("IKBranch/RodMechanism-v1", {"n_waypoints": 4}, (0, 1, 2)),
    ("IKBranch/RodMechanism-v1", {"n_waypoints": 4, "time_weight": 0.5}, (3,)),
    ("IKBranch/Spherical-v1", {"n_waypoints": 5}, (0, 1)),
    ("IKBranch/Cylindrical-v1", {"n_waypoints": 5, "terminate_on_collision": False}, (0, 1)),
    ("IKBranch/ToolTransfer-v0", {"n_waypoints": 3}, (0, 1)),
    ("IKBranch/Anthropomorphic-v1", {"n_waypoints": 3}, (4,)),
    ("IKBranch/DualRRPRPP-v0", {"n_waypoints": 5}, (0, 1)),
]
PARAMS = [
    pytest.param(env_id, kwargs, seed, id=f"{env_id.split('/')[1]}-{i}-s{seed}")
    for i, (env_id, kwargs, seeds) in enumerate(CASES)
    for seed in seeds
]


def play(env, policy, seed: int) -> tuple[float, list[int]]:
    obs, _ = env.reset(seed=seed)
    total, actions, done = 0.0, [], False
    while not done:
        action, _ = policy.predict(obs, action_masks=env.unwrapped.action_masks())
        obs, reward, terminated, truncated, _ = env.step(action)
        total += reward
        actions.append(int(action))
        done = terminated or truncated
    return total, actions


@pytest.mark.parametrize(("env_id", "kwargs", "seed"), PARAMS)
def test_oracle_is_the_brute_force_optimum_and_the_env_pays_its_plan(env_id, kwargs, seed):
    env = gym.make(env_id, **kwargs)
    oracle = make_baseline("dp_oracle", env)
    paid, actions = play(env, oracle, seed)
    assert actions == oracle.plan
    assert paid == pytest.approx(oracle.planned_return, rel=0, abs=1e-9)
    assert oracle.planned_return == pytest.approx(brute_force(env.unwrapped), rel=0, abs=1e-9)


@pytest.mark.parametrize(("env_id", "kwargs", "seed"), PARAMS[::2])
def test_receding_dp_with_the_whole_horizon_is_the_oracle(env_id, kwargs, seed):
    n = kwargs["n_waypoints"]
    oracle_env, receding_env = gym.make(env_id, **kwargs), gym.make(env_id, **kwargs)
    oracle_return, oracle_actions = play(oracle_env, DPOracle(oracle_env), seed)
    for horizon in (n, n + 3):
        paid, actions = play(receding_env, RecedingDP(receding_env, horizon=horizon), seed)
        assert actions == oracle_actions
        assert paid == pytest.approx(oracle_return, rel=0, abs=1e-9)
    short, _ = play(receding_env, RecedingDP(receding_env, horizon=1), seed)
    assert short <= oracle_return + 1e-9


def test_oracle_brute_force_by_replaying_every_sequence_in_the_env():
    """Independent of ``edge_rewards``: all K^N sequences played through ``step``."""
    env = gym.make("IKBranch/Spherical-v1", n_waypoints=4)
    oracle = DPOracle(env)
    paid, _ = play(env, oracle, seed=1)
    best = -np.inf
    k, n = env.unwrapped.arm.n_branches, 4
    for actions in itertools.product(range(k), repeat=n):
        env.reset(seed=1)
        total = 0.0
        for action in actions:
            _, reward, terminated, _, _ = env.step(action)
            total += reward
            if terminated:
                break
        best = max(best, total)
    assert paid == pytest.approx(best, rel=0, abs=1e-9)


def test_terminal_edges_end_the_plan():
    """A crash that ends the episode is worth its own reward only: nothing after it."""
    reward = [np.array([[-1.0, -50.0]]), np.array([[-100.0, -100.0], [-1.0, -1.0]])]
    terminal = [np.array([[False, True]]), np.array([[True, True], [True, True]])]
    tables = ladder_q_tables(list(zip(reward, terminal, strict=True)), np.ones((2, 2), bool))
    # Branch 0 then the only continuation: -101; the terminal crash at once: -50.
    assert tables[0][0].tolist() == [-101.0, -50.0]


def test_oracle_replans_when_the_env_draws_a_new_task_without_episode_start():
    env = gym.make("IKBranch/RodMechanism-v1", n_waypoints=4)
    oracle = DPOracle(env)
    obs, _ = env.reset(seed=0)
    oracle.predict(obs)
    first = oracle.planned_return
    obs, _ = env.reset(seed=1)
    oracle.predict(obs)  # no episode_start: the task object changed
    assert oracle.planned_return != first
    assert oracle.planned_return == pytest.approx(brute_force(env.unwrapped), abs=1e-9)


def test_receding_horizon_defaults_to_what_the_observation_shows():
    env = gym.make("IKBranch/RodMechanism-v1", lookahead=3)
    assert RecedingDP(env).horizon == 4
    with pytest.raises(ValueError, match="horizon"):
        RecedingDP(env, horizon=0)


RANDOM_WAYPOINT_IDS = [
    env_id for env_id, spec in envs.ENV_SPECS.items() if spec["task"] == "random"
]


@pytest.mark.parametrize("env_id", RANDOM_WAYPOINT_IDS)
def test_oracle_finishes_every_random_waypoint_task_without_a_collision(env_id):
    # The random task's generating chain is collision-free, so the optimum never crashes.
    env = gym.make(env_id, n_waypoints=4)
    oracle = make_baseline("dp_oracle", env)
    # Without the path check, seeds 0-7 include infeasible tasks for three of these ids.
    for seed in range(8):
        _, _ = play(env, oracle, seed)
        assert not env.unwrapped.episode_collided and not env.unwrapped.episode_invalid, seed


@pytest.mark.parametrize("env_id", [env_id for env_id, spec in envs.ENV_SPECS.items()
                                     if spec["task"] == "tool_changes"])
def test_oracle_finishes_every_tool_change_without_a_collision(env_id):
    # The cell is laid out so that every drawn tool change can be done collision-free
    # (for the IRB 4600 only the grip that fits under the spindle is drawn).
    env = gym.make(env_id)
    oracle = make_baseline("dp_oracle", env)
    for seed in range(30):
        _, _ = play(env, oracle, seed)
        assert not env.unwrapped.episode_collided and not env.unwrapped.episode_invalid, seed


def test_lazy_backward_pass_equals_ladder_q_tables():
    # The compiled backward pass over stacked edges is ladder_q_tables, bit for bit, with
    # missing rows, terminal edges and masked branches mixed in.
    from ikbranch_gym.agents.dp import _backward

    rng = np.random.default_rng(3)
    w, k = 6, 5
    reward = rng.normal(size=(w, k, k))
    reward[rng.random((w, k, k)) < 0.1] = np.nan
    reward[0, 1:] = np.nan  # waypoint 0 has one origin row
    terminal = rng.random((w, k, k)) < 0.2
    allowed = rng.random((w, k)) < 0.8
    allowed[:, 0] = True
    q = np.empty((w, k, k))
    _backward(reward, terminal, allowed, q)
    tables = ladder_q_tables([(reward[0, :1], terminal[0, :1])]
                             + [(reward[i], terminal[i]) for i in range(1, w)], allowed)
    np.testing.assert_array_equal(q[0, :1], tables[0])
    for i in range(1, w):
        np.testing.assert_array_equal(q[i], tables[i])


def test_lazy_oracle_checks_few_edges_and_replans_off_its_path():
    env = gym.make("IKBranch/ToolTransfer-v0", n_waypoints=40)
    oracle = DPOracle(env)
    obs, _ = env.reset(seed=5)
    oracle.predict(obs)
    base = env.unwrapped
    edges = 8 + 39 * 64
    assert oracle.lazy.checks < edges / 4
    # Push the arm off the plan (another valid branch), then ask again: the oracle's choice
    # is the best from where the arm now stands, by full pricing.
    mask = base.action_masks()
    other = next(b for b in np.flatnonzero(mask) if b != oracle.plan[0])
    obs, _, terminated, _, _ = env.step(other)
    assert not terminated
    action, _ = oracle.predict(obs)
    full = [base.edge_rewards(i) for i in range(1, base.task.n_waypoints)]
    tables = ladder_q_tables(full, base.valid[1:])
    assert int(action) == int(np.argmax(np.where(base.action_masks(), tables[0][other],
                                                 -np.inf)))


def test_values_equal_to_rounding_tie_towards_the_lower_branch():
    from ikbranch_gym.agents.dp import best_branch

    mask = np.ones(4, dtype=bool)
    value = -0.6575120052142036
    # The milling tool change's window (examples/README.md): four first branches whose
    # values differ in the last bits, differently with every IK rounding.
    for noise in ([0.0, -4e-16, 6e-16, 2e-16], [6e-16, 0.0, -4e-16, 2e-16]):
        assert best_branch(value + np.array(noise), mask) == 0
    assert best_branch(np.array([-1.0, -1.0 + 1e-6, -1.0, -1.0]), mask) == 1  # a real gap
    assert best_branch(np.array([-1.0, -0.5, -1.0, -2.0]), np.array([1, 0, 1, 1], bool)) == 0
    assert best_branch(np.array([-5.0, -np.inf, -3.0, -3.0]), np.array([1, 1, 0, 1], bool)) == 3
    assert best_branch(np.full(4, -np.inf), mask) == 0  # nothing finite: as argmax
