"""``random``: FK of random collision-free configurations, for every arm."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym  # noqa: F401  (registers the ids)
from ikbranch_gym.envs.kinematics import ARM_NAMES, make_arm
from ikbranch_gym.envs.tasks import TASKS
from ikbranch_gym.envs.tasks.base import RangedArm
from tests.envs.tasks.helpers import (
    all_paths_free,
    assert_every_waypoint_has_a_free_branch,
    assert_same_task,
    half_space,
    nowhere_free,
)

generator = TASKS["random"]


@pytest.mark.parametrize("arm_name", ARM_NAMES)
def test_deterministic_and_every_waypoint_has_a_free_branch(arm_name):
    arm = make_arm(arm_name)
    is_free = half_space(arm)
    generator.check_arm(arm, "empty")  # every arm
    task = generator(arm, np.random.default_rng(4), 5, is_free, all_paths_free)
    assert task.poses.shape == (5, 4, 4) and not task.free_start
    assert_same_task(task, generator(arm, np.random.default_rng(4), 5, is_free, all_paths_free))
    assert not np.array_equal(
        task.poses, generator(arm, np.random.default_rng(5), 5, is_free, all_paths_free).poses
    )
    assert_every_waypoint_has_a_free_branch(arm, task, is_free)
    assert np.all(arm.within_limits(task.start))


def test_a_scene_without_free_space_is_reported():
    arm = make_arm("cartesian")
    with pytest.raises(RuntimeError, match="collision-free"):
        generator(
            arm, np.random.default_rng(0), 3, nowhere_free, all_paths_free
        )


def test_consecutive_waypoints_are_joined_by_a_free_path():
    # Paths that turn φ1 by more than a sixth of its range are "blocked": the task must
    # still have a chain of branches, start to last waypoint, made of allowed paths.
    arm = make_arm("anthropomorphic")
    is_free = half_space(arm)
    limit = np.ptp(arm.joint_limits[0]) / 6

    def short_turns(q0, q1):
        return np.abs(np.asarray(q1)[:, 0] - np.asarray(q0)[:, 0]) <= limit

    blocked = 0
    for seed in range(10):
        task = generator(arm, np.random.default_rng(seed), 6, is_free, short_turns)
        candidates, valid = arm.ik(task.poses)
        reachable = [task.start]
        for rows, ok in zip(candidates, valid, strict=True):
            rows = rows[ok]
            allowed = np.array(
                [short_turns(np.array(reachable), np.repeat(q[None], len(reachable), 0)).any()
                 for q in rows]
            )
            reachable = list(rows[allowed])
            assert reachable, f"seed {seed}: no free path into a waypoint"
        unchecked = generator(arm, np.random.default_rng(seed), 6, is_free, all_paths_free)
        blocked += not np.array_equal(unchecked.poses, task.poses)
    assert blocked > 0  # the predicate really redrew some waypoints


def test_a_chain_that_cannot_move_is_reported():
    arm = make_arm("cartesian")
    with pytest.raises(RuntimeError, match="no chain of collision-free paths"):
        generator(
            arm, np.random.default_rng(0), 3, half_space(arm),
            lambda q0, q1: np.zeros(len(q0), dtype=bool),
        )


def test_no_link_is_checked_while_its_start_may_still_be_redrawn():
    # A call asks the link the walk stands at and later ones, never the link right after
    # it: a redraw of the configuration between them would waste that check. Each link
    # (its two configurations) is asked once, and the walk is the one-at-a-time walk.
    arm = make_arm("anthropomorphic")
    is_free = half_space(arm)
    limit = np.ptp(arm.joint_limits[0]) / 6
    calls: list[list[tuple[bytes, bytes]]] = []

    def short_turns(q0, q1):
        calls.append([(a.tobytes(), b.tobytes()) for a, b in zip(q0, q1, strict=True)])
        return np.abs(np.asarray(q1)[:, 0] - np.asarray(q0)[:, 0]) <= limit

    def one_at_a_time(q0, q1):
        return np.array([short_turns(q0[i : i + 1], q1[i : i + 1])[0]
                         for i in range(len(q0))])

    for seed in range(5):
        calls.clear()
        task = generator(arm, np.random.default_rng(seed), 6, is_free, short_turns)
        for call in calls:  # the first link asked is where the walk stands
            assert not any(start == call[0][1] for start, _ in call[1:])
        asked = [link for call in calls for link in call]
        assert len(asked) == len(set(asked))
        assert_same_task(task, generator(arm, np.random.default_rng(seed), 6, is_free,
                                         one_at_a_time))


def test_a_joint_range_keeps_every_draw_inside_it_and_the_arm_as_it_is():
    arm = make_arm("ur5e")
    one_turn = np.clip(arm.joint_limits, -np.pi, np.pi)
    ranged = RangedArm(arm, one_turn)
    q = np.random.default_rng(0).uniform(-6.0, 6.0, (4, arm.dof))
    np.testing.assert_array_equal(ranged.fk(q), arm.fk(q))
    assert ranged.n_branches == arm.n_branches == 256
    for seed in range(5):
        task = generator(ranged, np.random.default_rng(seed), 4, half_space(arm),
                         all_paths_free)
        assert np.all(np.abs(task.start) <= np.pi)
        # each waypoint is the pose of a configuration inside the range: one of its branches
        candidates, valid = arm.ik(task.poses)
        inside = valid & np.all(np.abs(candidates) <= np.pi + 1e-9, axis=-1)
        assert inside.any(axis=-1).all()
        assert (valid & ~inside).any(axis=-1).all()  # the other turns stay branches
    # The arm's own limits reach two turns: unranged, the starts leave [−π, π].
    starts = np.array([generator(arm, np.random.default_rng(seed), 4, half_space(arm),
                                 all_paths_free).start for seed in range(5)])
    assert np.any(np.abs(starts) > np.pi)


def test_ur5e_v4_draws_its_tasks_within_one_turn_and_v3_does_not():
    kept = {}
    for env_id in ("IKBranch/UR5e-v3", "IKBranch/UR5e-v4"):
        env = gym.make(env_id).unwrapped
        starts = []
        for seed in range(4):
            env.reset(seed=seed)
            starts.append(env.task.start)
            assert env.action_space.n == 256
        kept[env_id] = np.abs(np.array(starts)).max()
        env.close()
    assert kept["IKBranch/UR5e-v4"] <= np.pi < kept["IKBranch/UR5e-v3"]
