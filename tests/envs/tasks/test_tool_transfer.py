"""The milling cell's tasks: the paper's transfer and tool changes (rack slot ↔ spindle)."""

from __future__ import annotations

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import ARM_NAMES, make_arm
from ikbranch_gym.envs.kinematics.paper_example import example_poses, rack_slot_poses
from ikbranch_gym.envs.models import CollisionChecker, build_arm_model
from ikbranch_gym.envs.tasks import TASKS, tool_transfer
from ikbranch_gym.envs.tasks.tool_transfer import RACK_CLEARANCE, _parked_configurations
from tests.envs.tasks.helpers import (
    all_paths_free,
    assert_every_waypoint_has_a_free_branch,
    assert_same_task,
    nowhere_free,
)

ARM = make_arm("anthropomorphic")


def _never_called(q):
    raise AssertionError("the paper's transfer has fixed poses: no sampling")


def _everything_free(q):
    return np.ones(len(q), dtype=bool)


def _same_pose_up_to_grip(pose, reference):
    """Equal position and tool axis y3; x3/z3 either way round (the two grips)."""
    return (
        np.allclose(pose[:3, 3], reference[:3, 3])
        and np.allclose(pose[:3, 1], reference[:3, 1])
        and np.allclose(np.abs(pose[:3, [0, 2]]), np.abs(reference[:3, [0, 2]]))
    )


def test_tool_changes_cycle_above_slot_slot_above_slot_spindle():
    rng = np.random.default_rng(0)
    task = TASKS["tool_changes"](ARM, rng, 8, _everything_free, all_paths_free)
    again = TASKS["tool_changes"](
        ARM, np.random.default_rng(0), 8, _everything_free, all_paths_free
    )
    assert_same_task(task, again)
    slots, spindle = rack_slot_poses(), example_poses()[1]
    assert not task.free_start and len(task.poses) == 8
    for tool in range(2):
        above, slot, above_again, into = task.poses[4 * tool : 4 * tool + 4]
        assert any(_same_pose_up_to_grip(slot, s) for s in slots)
        assert np.array_equal(above, above_again)
        np.testing.assert_allclose(above[:3, 3] - slot[:3, 3], [0.0, 0.0, RACK_CLEARANCE])
        assert _same_pose_up_to_grip(into, spindle)
        # One grip per tool, from the rack to the spindle: the same turn about y3 at both.
        grip_at_rack = slots[0][:3, :3].T @ slot[:3, :3]
        grip_at_spindle = spindle[:3, :3].T @ into[:3, :3]
        np.testing.assert_allclose(grip_at_rack, grip_at_spindle, atol=1e-12)
    drawn = [
        TASKS["tool_changes"](ARM, np.random.default_rng(seed), 8, _everything_free, all_paths_free)
        for seed in range(20)
    ]
    used_slots = {
        int(np.argmin([np.linalg.norm(t.poses[1][:3, 3] - s[:3, 3]) for s in slots])) for t in drawn
    }
    assert used_slots == set(range(len(slots)))  # every slot gets drawn
    grips = {int(np.sign(t.poses[1][2, 0])) for t in drawn}  # x3 down or up
    assert len(grips) == 2  # both grips get drawn
    starts = {t.start.tobytes() for t in drawn}
    assert len(starts) > 5  # the start is where an earlier job left the arm, not fixed
    # Cut anywhere: the first waypoints of the same cycle.
    short = TASKS["tool_changes"](
        ARM, np.random.default_rng(0), 3, _everything_free, all_paths_free
    )
    np.testing.assert_array_equal(short.poses, task.poses[:3])


@pytest.mark.parametrize("n_waypoints", [3, 8, 9])
def test_tool_changes_draw_as_arrays_of_draws(n_waypoints):
    """The slots, grips and start are the draws of ``integers(…, size=tools)`` as NumPy
    makes them, then one for the start: a task, and the generator's state after it, as
    drawn in arrays (the published runs' tasks)."""
    slots, spindle = rack_slot_poses(), example_poses()[1]
    grips = (np.eye(3), np.diag([-1.0, 1.0, -1.0]))
    parked = _parked_configurations(ARM)
    tools = -(-n_waypoints // 4)
    for seed in range(40):
        task = TASKS["tool_changes"](ARM, np.random.default_rng(seed), n_waypoints,
                                     _everything_free, all_paths_free)
        rng = np.random.default_rng(seed)
        grip = rng.integers(2, size=tools)
        slot = rng.integers(len(slots), size=tools)
        start = parked[rng.integers(len(parked))]
        poses = []
        for g, k in zip(grip, slot, strict=True):
            held = slots[k].copy()
            held[:3, :3] = slots[k][:3, :3] @ grips[g]
            above = held.copy()
            above[2, 3] += RACK_CLEARANCE
            into = spindle.copy()
            into[:3, :3] = spindle[:3, :3] @ grips[g]
            poses += [above, held, above, into]
        np.testing.assert_array_equal(task.start, start)
        np.testing.assert_array_equal(task.poses, np.array(poses)[:n_waypoints])
        after = np.random.default_rng(seed)
        TASKS["tool_changes"](ARM, after, n_waypoints, _everything_free, all_paths_free)
        # The whole state, the buffered half of a 64-bit draw included.
        assert after.bit_generator.state == rng.bit_generator.state


def test_tool_changes_start_collision_free():
    parked = _parked_configurations(ARM)

    def is_free(q, need=None):  # forbid every parked start but home
        q = np.asarray(q)
        taken = (q[:, None, :] == parked[None, 1:, :]).all(axis=-1).any(axis=1)
        return ~taken

    task = TASKS["tool_changes"](ARM, np.random.default_rng(4), 8, is_free, all_paths_free)
    np.testing.assert_array_equal(task.start, ARM.home)


def test_tool_changes_poses_have_free_branches_in_the_milling_cell():
    checker = CollisionChecker(build_arm_model(ARM, "milling_cell"), dof=ARM.dof)

    def is_free(q, need=None):
        return ~checker.collides(q)

    task = TASKS["tool_changes"](ARM, np.random.default_rng(0), 6, is_free, all_paths_free)
    assert_every_waypoint_has_a_free_branch(ARM, task, is_free)


def test_the_generated_poses_are_not_shared_state():
    first = TASKS["tool_changes"](
        ARM, np.random.default_rng(0), 4, _everything_free, all_paths_free
    )
    expected = first.poses.copy()
    first.poses[:] = 0.0  # a caller scribbling on its task must not change the next one
    second = TASKS["tool_changes"](
        ARM, np.random.default_rng(0), 4, _everything_free, all_paths_free
    )
    assert np.array_equal(second.poses, expected)


def test_paper_transfer_is_the_worked_example():
    task = TASKS["paper_transfer"](ARM, np.random.default_rng(0), 2, _never_called, all_paths_free)
    assert task.free_start and np.array_equal(task.poses, example_poses())
    assert TASKS["paper_transfer"].fixed_waypoints
    with pytest.raises(ValueError, match="exactly 2"):
        TASKS["paper_transfer"](ARM, np.random.default_rng(0), 3, _never_called, all_paths_free)


@pytest.mark.parametrize("arm_name", [n for n in ARM_NAMES if n != "anthropomorphic"])
def test_the_papers_transfer_needs_the_anthropomorphic_arm(arm_name):
    with pytest.raises(ValueError, match="anthropomorphic"):
        TASKS["paper_transfer"].check_arm(make_arm(arm_name), "milling_cell")


#: Not six-DOF single arms: four joints, a position-only mechanism, the two-arm systems.
NOT_SIX_DOF_SINGLE = {"cylindrical4", "rod_mechanism", "dual_rrp_rpp", "dual_rrr_ppp",
                      "dual_ppr_prr"}


@pytest.mark.parametrize("arm_name", ARM_NAMES)
def test_tool_changes_need_a_six_dof_single_arm(arm_name):
    arm = make_arm(arm_name)
    if arm_name not in NOT_SIX_DOF_SINGLE:
        TASKS["tool_changes"].check_arm(arm, "milling_cell")  # any such arm, placed in it
    else:
        with pytest.raises(ValueError, match="six-DOF single arm"):
            TASKS["tool_changes"].check_arm(arm, "milling_cell")


def test_tool_changes_need_the_milling_cell():
    TASKS["tool_changes"].check_arm(ARM, "milling_cell")
    for scene in ("empty", "random_clutter"):
        with pytest.raises(ValueError, match="milling_cell"):
            TASKS["tool_changes"].check_arm(ARM, scene)
    TASKS["paper_transfer"].check_arm(ARM, "empty")  # the transfer itself runs anywhere


def test_tool_changes_take_only_grips_whose_every_pose_has_a_free_branch():
    # A scene where the spindle is blocked for grip 0: only grip 1 is ever drawn.
    _, _, spindle = tool_transfer._cell_poses()
    blocked, valid = ARM.ik(spindle[0])
    blocked = blocked[valid]

    def is_free(q, need=None):
        q = np.asarray(q)
        return ~(np.abs(q[:, None, :] - blocked[None]) < 1e-9).all(axis=-1).any(axis=1)

    rng = np.random.default_rng(0)
    for _ in range(20):
        task = TASKS["tool_changes"](ARM, rng, 8, is_free, all_paths_free)
        for tool in range(2):
            assert np.allclose(task.poses[4 * tool + 3], spindle[1])
    with pytest.raises(ValueError, match="cannot change tools"):
        TASKS["tool_changes"](ARM, rng, 8, nowhere_free, all_paths_free)


def test_the_free_parked_starts_are_the_parked_configurations_the_predicate_passes():
    from ikbranch_gym.envs.tasks.tool_transfer import _free_parked_configurations

    parked = _parked_configurations(ARM)

    def is_free(q, need=None):  # every other parked configuration
        return np.arange(len(q)) % 2 == 0

    free = _free_parked_configurations(ARM, is_free)
    np.testing.assert_array_equal(free, parked[::2])
    assert not free.flags.writeable
    assert _free_parked_configurations(ARM, is_free) is free  # asked once per predicate
