"""The collision checker seen from outside: a second collision library (coal) re-measures
the collision shapes along the moves the env judged, on the env's own path grid, and
certifies that the drawn shapes stay apart along every free move, between the samples
too."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from ikbranch_gym.agents import make_baseline
from ikbranch_gym.envs import CURRENT_IDS
from ikbranch_gym.envs.models.independent import Measure
from ikbranch_gym.envs.seeds import held_out

#: coal's and MuJoCo's distances agree to well below this (m).
TOLERANCE = 1e-5


@pytest.mark.parametrize("env_id", ["IKBranch/UR5e-v1", "IKBranch/KukaKR6-v1",
                                    "IKBranch/Anthropomorphic-v3", "IKBranch/ToolTransfer-v2",
                                    "IKBranch/DualRRPRPP-v2"])
def test_coal_agrees_with_every_verdict_on_the_collision_shapes(env_id):
    # Free moves keep every tested pair at least δ apart at every grid sample; a move the
    # env paid a collision for has a sample where some pair is closer than δ.
    env = gym.make(env_id, **held_out(env_id))
    base = env.unwrapped
    probe, checker = Measure(env), base.checker
    oracle = make_baseline("dp_oracle", env)
    rng = np.random.default_rng(0)
    delta = checker.resolution
    free_nearest, free, colliding = np.inf, 0, 0
    for episode in range(6):
        obs, info = env.reset(seed=episode)
        probe.refresh()
        done = False
        while not done:
            before = base.q
            if episode % 2 == 0:  # the optimum's moves, and random ones (near misses, hits)
                action = int(oracle.predict(obs, action_masks=info["action_mask"])[0])
            else:
                action = int(rng.choice(np.flatnonzero(info["action_mask"])))
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            nearest = min(float(probe.distances(q, probe.collision).min())
                          for q in checker.path_samples(before, base.q))
            if info["reward_collision"] == 0.0:
                free += 1
                free_nearest = min(free_nearest, nearest)
                assert nearest >= delta - TOLERANCE, (episode, nearest)
            else:
                colliding += 1
                assert nearest < delta + TOLERANCE, (episode, nearest)
    assert free >= 10
    # The check met free moves near the margin, not only far from everything.
    assert free_nearest < delta + 0.1


def _free_moves(env_id: str, episodes: int):
    """(env, Measure, start, end) of every move the env paid no collision for in seeded
    held-out episodes, played alternately by the DP oracle and masked random actions."""
    env = gym.make(env_id, **held_out(env_id))
    base = env.unwrapped
    probe = Measure(env)
    oracle = make_baseline("dp_oracle", env)
    rng = np.random.default_rng(3)
    for episode in range(episodes):
        obs, info = env.reset(seed=100 + episode)
        probe.refresh()
        done = False
        while not done:
            before = base.q
            if episode % 2 == 0:
                action = int(oracle.predict(obs, action_masks=info["action_mask"])[0])
            else:
                action = int(rng.choice(np.flatnonzero(info["action_mask"])))
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            if info["reward_collision"] == 0.0 and not info["invalid"]:
                yield env, probe, before, base.q


@pytest.mark.parametrize("env_id", CURRENT_IDS)
def test_every_free_move_keeps_the_drawn_shapes_apart_all_along(env_id):
    # Every body pair the checker tests, between their drawn shapes, and the drawn shapes
    # of the pairs an exclusion hides: certified apart on the whole move, not only at the
    # samples.
    moves = 0
    for _, probe, start, end in _free_moves(env_id, 4):
        pairs = np.concatenate([probe.drawn, probe.excluded])
        clearance = probe.certify(start, end, pairs)
        assert clearance.certified, (moves, clearance)
        assert clearance.least >= 0.0
        moves += 1
    assert moves >= 8


def test_the_certificate_finds_what_the_earlier_models_hid():
    # The check above can fail: the earlier Anthropomorphic wrist excluded its roll
    # housing from its flange, and their drawn shapes overlap in free moves.
    found = []
    for _, probe, start, end in _free_moves("IKBranch/Anthropomorphic-v2", 2):
        clearance = probe.certify(start, end, probe.excluded)
        if not clearance.certified:
            found.append(clearance.least)
    assert found and min(found) < -0.01


def test_a_certificate_holds_between_the_samples():
    # Two moves between the same two poses of the UR5e, the arm raised 69° either side of
    # upright: over the top, and the other way round through the floor. Their ends are the
    # same distances from the floor; only the middle of the second penetrates it.
    env = gym.make("IKBranch/UR5e-v1", **held_out("IKBranch/UR5e-v1"))
    env.reset(seed=0)
    probe = Measure(env)
    model = env.unwrapped.model
    floor = model.geom("floor").id
    pairs = probe.drawn[(probe.drawn == floor).any(axis=1)]
    assert len(pairs) >= 5
    upright = np.array([0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0])
    start, over, under = upright.copy(), upright.copy(), upright.copy()
    start[1] -= 1.2
    over[1] += 1.2
    under[1] += 1.2 - 2 * np.pi  # the same pose, reached the other way round
    assert probe.lower_bounds(start, pairs).min() > 0.05
    np.testing.assert_allclose(probe.lower_bounds(over, pairs),
                               probe.lower_bounds(under, pairs), atol=1e-9)
    over_the_top = probe.certify(start, over, pairs)
    through_the_floor = probe.certify(start, under, pairs)
    assert over_the_top.certified and over_the_top.least > 0.05
    assert not through_the_floor.certified and through_the_floor.least < -0.1


def test_allowed_contacts_alone_leave_the_independent_check():
    # The deburring id lets the burr (tool_1) touch the part: those drawn pairs are the
    # job; the spindle (tool) against the part, and the burr against the clamps, are still
    # measured.
    env = gym.make("IKBranch/KukaKR6Deburring-v1")
    env.reset(seed=0)
    probe = Measure(env)
    model = env.unwrapped.model
    names = {tuple(sorted((model.geom(a).name, model.geom(b).name))) for a, b in probe.drawn}
    assert not any(a.startswith("part") and b == "tool_1_vis" for a, b in names)
    assert ("part_vis", "tool_vis") in names
    assert ("clamp_left_vis", "tool_1_vis") in names
