"""The random task's compiled chain is the generator's: the same tasks, the same generator
state after, the same errors."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs as envs
from ikbranch_gym.envs.costs import TransitionCost
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import CollisionChecker, arm_spec
from ikbranch_gym.envs.models.builders import add_part, add_static_body, compile_spec
from ikbranch_gym.envs.moves import MovePricer
from ikbranch_gym.envs.random_chain import random_chain
from ikbranch_gym.envs.tasks.random_reachable import random_reachable

RANDOM_IDS = [env_id for env_id, kwargs in envs.ENV_SPECS.items() if kwargs["task"] == "random"]


def _twins(rng: np.random.Generator) -> tuple[np.random.Generator, np.random.Generator]:
    state = rng.bit_generator.state
    twins = []
    for _ in range(2):
        twin = np.random.Generator(np.random.PCG64())
        twin.bit_generator.state = state
        twins.append(twin)
    return twins[0], twins[1]


@pytest.mark.parametrize("env_id", RANDOM_IDS)
def test_the_compiled_chain_is_the_generators(env_id):
    env = gym.make(env_id, n_waypoints=5).unwrapped
    for seed in range(12 if "UR5e" not in env_id else 4):
        env.reset(seed=seed)  # a scene laid, a generator mid-stream
        python, compiled = _twins(env.np_random)
        expected = random_reachable(env._task_arm, python, env.n_waypoints, env.pricer.is_free,
                                    env.pricer.is_path_free)
        task = random_chain(env._task_arm, compiled, env.n_waypoints, env.checker._filter,
                            env.checker.lever, env.checker.resolution)
        np.testing.assert_array_equal(task.start, expected.start)
        np.testing.assert_array_equal(task.poses, expected.poses)
        assert compiled.bit_generator.state == python.bit_generator.state


def test_a_scene_with_no_free_configuration_fails_alike():
    # A box around the arm's base: every configuration collides.
    arm = make_arm("cartesian")
    spec, _ = arm_spec(arm)
    add_part(add_static_body(spec, "crate"), "crate", "box", [3.0, 3.0, 3.0], (1, 1, 1, 1))
    checker = CollisionChecker(compile_spec(spec), dof=arm.dof)
    pricer = MovePricer(arm, checker, TransitionCost.for_arm(arm), collision_penalty=1.0,
                        invalid_penalty=1.0, terminate_on_collision=True)
    python, compiled = _twins(np.random.default_rng(1))
    with pytest.raises(RuntimeError) as expected:
        random_reachable(arm, python, 3, pricer.is_free, pricer.is_path_free)
    with pytest.raises(RuntimeError) as raised:
        random_chain(arm, compiled, 3, checker._filter, checker.lever, checker.resolution)
    assert str(raised.value) == str(expected.value)
    assert "found only 0 of 4 collision-free configurations in 2000 rounds" in str(raised.value)
    assert compiled.bit_generator.state == python.bit_generator.state
