"""``helix``, ``circle`` and ``line``: the gripper on the path's Frenet frame (eq. 7), or
at constant orientation along a line."""

from __future__ import annotations

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.tasks import TASKS
from ikbranch_gym.envs.tasks.paths import TOOL_OFFSET
from tests.envs.tasks.helpers import (
    all_paths_free,
    assert_every_waypoint_has_a_free_branch,
    assert_same_task,
    half_space,
)

POSE_ARMS = ("cartesian", "cylindrical", "spherical", "anthropomorphic")
# circle with its default 8 waypoints is only reachable for the anthropomorphic arm (the
# other three arms' wrists never fit a full horizontal Frenet circle): see the report.
CASES = [(t, a) for t in ("helix", "line") for a in POSE_ARMS] + [("circle", "anthropomorphic")]


def _object_points(poses):
    """The object point r(t): TOOL_OFFSET ahead of the wrist centre along y."""
    return poses[:, :3, 3] + TOOL_OFFSET * poses[:, :3, 1]


@pytest.mark.parametrize(("task_name", "arm_name"), CASES)
def test_deterministic_and_every_waypoint_has_a_free_branch(task_name, arm_name):
    arm, generator = make_arm(arm_name), TASKS[task_name]
    is_free = half_space(arm)
    task = generator(arm, np.random.default_rng(1), 6, is_free, all_paths_free)
    assert task.poses.shape == (6, 4, 4)
    assert_same_task(task, generator(arm, np.random.default_rng(1), 6, is_free, all_paths_free))
    assert_every_waypoint_has_a_free_branch(arm, task, is_free)
    rotations = task.poses[:, :3, :3]
    assert np.allclose(rotations @ rotations.transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(rotations), 1.0)


def _horizontal_centre(points, normals):
    """Least-squares ρ and centre c with c = p_i + ρ·n_i (xy) for every waypoint."""
    a = np.zeros((2 * len(points), 3))
    a[:, :2] = np.tile(np.eye(2), (len(points), 1))
    a[:, 2] = -normals[:, :2].reshape(-1)
    solution, *_ = np.linalg.lstsq(a, points[:, :2].reshape(-1), rcond=None)
    return solution[:2], solution[2]


@pytest.mark.parametrize("task_name", ["helix", "circle"])
def test_curves_carry_the_frenet_frame(task_name):
    arm = make_arm("anthropomorphic")
    for seed in range(3):
        poses = TASKS[task_name](
            arm, np.random.default_rng(seed), 8, half_space(arm), all_paths_free
        ).poses
        x, y, z = (poses[:, :3, i] for i in range(3))
        points = _object_points(poses)
        # Principal normal: horizontal and pointing at the (vertical) axis, all the same
        # distance away; binormal = tangent × normal.
        assert np.allclose(y[:, 2], 0.0, atol=1e-12)
        centre, radius = _horizontal_centre(points, y)
        assert 0.08 - 1e-9 <= radius <= 0.25 + 1e-9
        assert np.allclose(points[:, :2] + radius * y[:, :2], centre, atol=1e-9)
        assert np.allclose(np.cross(x, y), z, atol=1e-12)
        # Tangent: perpendicular to the radius, climbing at a constant rate (the pitch).
        assert np.allclose(np.einsum("ij,ij->i", x, y), 0.0, atol=1e-12)
        assert np.allclose(x[:, 2], x[0, 2], atol=1e-12)
        heights = points[:, 2]
        if task_name == "circle":
            assert np.allclose(x[:, 2], 0.0, atol=1e-12) and np.allclose(heights, heights[0])
            chords = np.linalg.norm(np.diff(points, axis=0), axis=1)
            assert np.allclose(chords, chords[0])  # evenly sampled
        else:
            steps = np.diff(heights)
            assert np.allclose(steps, steps[0], atol=1e-12)  # constant pitch
            assert np.isclose(np.sign(steps[0]) * np.abs(x[0, 2]), x[0, 2]) or steps[0] == 0


def test_line_keeps_a_constant_orientation_along_a_straight_segment():
    arm = make_arm("anthropomorphic")
    for seed in range(3):
        poses = TASKS["line"](
            arm, np.random.default_rng(seed), 7, half_space(arm), all_paths_free
        ).poses
        assert np.array_equal(poses[1:, :3, :3], np.broadcast_to(poses[0, :3, :3], (6, 3, 3)))
        offsets = poses[:, :3, 3] - poses[0, :3, 3]
        length = np.linalg.norm(offsets[-1])
        assert 0.2 - 1e-9 <= length <= 0.6 + 1e-9
        direction = offsets[-1] / length
        assert np.allclose(offsets, np.linspace(0, length, 7)[:, None] * direction, atol=1e-12)


@pytest.mark.parametrize("task_name", ["helix", "circle", "line"])
@pytest.mark.parametrize(
    "arm_name", ["cylindrical4", "rod_mechanism", "dual_rrp_rpp", "dual_rrr_ppp", "dual_ppr_prr"]
)
def test_paths_need_a_six_dof_single_arm(task_name, arm_name):
    with pytest.raises(ValueError, match="six-DOF single arm"):
        TASKS[task_name].check_arm(make_arm(arm_name), "empty")
    for arm_name in POSE_ARMS:
        TASKS[task_name].check_arm(make_arm(arm_name), "empty")  # no error
