"""``relative_motion``: the relative pose M34 of a two-arm system along a joint sweep."""

from __future__ import annotations

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import ARM_NAMES, make_arm
from ikbranch_gym.envs.tasks import TASKS
from tests.envs.tasks.helpers import (
    all_paths_free,
    assert_every_waypoint_has_a_free_branch,
    assert_same_task,
    half_space,
)

generator = TASKS["relative_motion"]
DUALS = [name for name in ARM_NAMES if make_arm(name).relative]


@pytest.mark.parametrize("arm_name", DUALS)
def test_deterministic_reachable_and_free(arm_name):
    arm = make_arm(arm_name)
    is_free = half_space(arm)
    task = generator(arm, np.random.default_rng(2), 8, is_free, all_paths_free)
    assert task.poses.shape == (8, 4, 4)
    assert_same_task(task, generator(arm, np.random.default_rng(2), 8, is_free, all_paths_free))
    assert_every_waypoint_has_a_free_branch(arm, task, is_free)
    # The sweep ends where it is going: the last waypoint is fk of a free configuration
    # that the IK reproduces, and the first lies near the start (cosine easing).
    candidates, valid = arm.ik(task.poses[:1])
    nearest = np.nanmin(np.abs(candidates[0][valid[0]] - task.start).sum(axis=-1))
    assert nearest < np.abs(np.diff(arm.joint_limits, axis=1)).sum()


@pytest.mark.parametrize("arm_name", [n for n in ARM_NAMES if not make_arm(n).relative])
def test_needs_a_two_arm_system(arm_name):
    with pytest.raises(ValueError, match="two-arm"):
        generator.check_arm(make_arm(arm_name), "empty")
