"""The collision checker seen from outside: a second collision library (coal) re-measures
the collision shapes along the moves the env judged, on the env's own path grid."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs  # noqa: F401  (registers the ids)
from ikbranch_gym.agents import make_baseline
from ikbranch_gym.envs.models.independent import Measure
from ikbranch_gym.envs.seeds import held_out

#: coal's and MuJoCo's distances agree to well below this (m).
TOLERANCE = 1e-5


@pytest.mark.parametrize("env_id", ["IKBranch/UR5e-v0", "IKBranch/KukaKR6-v0",
                                    "IKBranch/Anthropomorphic-v2", "IKBranch/ToolTransfer-v1",
                                    "IKBranch/DualRRPRPP-v1"])
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
