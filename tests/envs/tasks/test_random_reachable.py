"""``random``: FK of random collision-free configurations, for every arm."""

from __future__ import annotations

import numpy as np
import pytest

from envs.kinematics import ARM_NAMES, make_arm
from envs.tasks import TASKS
from tests.envs.tasks.helpers import (
    assert_every_waypoint_has_a_free_branch,
    assert_same_task,
    half_space,
)

generator = TASKS["random"]


@pytest.mark.parametrize("arm_name", ARM_NAMES)
def test_deterministic_and_every_waypoint_has_a_free_branch(arm_name):
    arm = make_arm(arm_name)
    is_free = half_space(arm)
    generator.check_arm(arm, "empty")  # every arm
    task = generator(arm, np.random.default_rng(4), 5, is_free)
    assert task.poses.shape == (5, 4, 4) and not task.free_start
    assert_same_task(task, generator(arm, np.random.default_rng(4), 5, is_free))
    assert not np.array_equal(task.poses, generator(arm, np.random.default_rng(5), 5,
                                                    is_free).poses)
    assert_every_waypoint_has_a_free_branch(arm, task, is_free)
    assert np.all(arm.within_limits(task.start))


def test_a_scene_without_free_space_is_reported():
    arm = make_arm("cartesian")
    with pytest.raises(RuntimeError, match="collision-free"):
        generator(arm, np.random.default_rng(0), 3, lambda q: np.zeros(len(q), dtype=bool))
