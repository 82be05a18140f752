"""The deburring task: a pass of the burr along the part's rounded rim, one process
segment, kept only when the arm can follow it; and its registered id, where the burr's
spin is part of the action."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import ikbranch_gym.envs  # noqa: F401
from ikbranch_gym.agents import make_baseline
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.singularities import singularity_margins
from ikbranch_gym.envs.tasks.deburring import (
    CHAMFER_RANGE,
    CORNER_RADIUS,
    PART_CENTRE,
    PART_HALF,
    PART_TOP,
    START,
    followable_chain,
    rim_poses,
    rim_samples,
)
from tests.envs.tasks.helpers import all_paths_free, everywhere_free

ID = "IKBranch/KukaKR6Deburring-v1"


def _rim_distance(points: np.ndarray) -> np.ndarray:
    """Distance of (M, 3) points from the rounded rectangle of the rim (its own formula:
    the distance to the inner rectangle, less the corner radius)."""
    inner = np.array(PART_HALF) - CORNER_RADIUS
    d = np.abs(points[:, :2] - np.array(PART_CENTRE)) - inner
    outside = np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)
    return np.abs(outside - CORNER_RADIUS)


def test_the_rim_is_sampled_along_edges_and_around_corners():
    points, normals, tangents = rim_samples()
    assert len(points) == 48  # 5 + 7 + 5 + 7 edge samples, 6 per corner
    assert np.all(points[:, 2] == PART_TOP)
    assert _rim_distance(points).max() < 1e-12
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose((normals * tangents).sum(axis=1), 0.0, atol=1e-12)
    # Anticlockwise seen from above, the loop closed: every step forward along its tangent,
    # at most 20 mm along an edge, 15° of normal around a corner.
    steps = np.diff(np.r_[points, points[:1]], axis=0)
    assert np.all((steps * tangents).sum(axis=1) > 0.0)
    assert np.linalg.norm(steps, axis=1).max() < 0.0195
    cosines = np.clip((normals * np.roll(normals, -1, axis=0)).sum(axis=1), -1.0, 1.0)
    turns = np.degrees(np.arccos(cosines))
    assert sorted(set(np.round(turns, 9))) == [0.0, 15.0]
    assert np.ptp(np.degrees(np.arctan2(normals[:, 1], normals[:, 0]))) > 180.0  # all round


def test_a_rim_pose_points_the_burr_into_the_edge():
    points, normals, tangents = rim_samples()
    chamfer = math.radians(40.0)
    poses = rim_poses(points, normals, tangents, chamfer)
    for pose, n, t in zip(poses, normals, tangents, strict=True):
        rotation = pose[:3, :3]
        np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)
        assert np.linalg.det(rotation) == pytest.approx(1.0)
        np.testing.assert_allclose(rotation[:, 0], t, atol=1e-12)  # x along the travel
        # z into the edge: down, and into the part by the chamfer angle.
        np.testing.assert_allclose(rotation[:, 2],
                                   -(math.sin(chamfer) * n + math.cos(chamfer) * np.eye(3)[2]),
                                   atol=1e-12)


def test_a_pass_is_one_segment_of_neighbouring_rim_points():
    arm = make_arm("kuka_kr6_r700")
    points, _, _ = rim_samples()
    rng = np.random.default_rng(1)
    from ikbranch_gym.envs.tasks import TASKS

    for _ in range(4):
        task = TASKS["deburring"](arm, rng, 12, everywhere_free, all_paths_free)
        assert task.n_waypoints == 12 and not task.free_start
        np.testing.assert_array_equal(task.segments, np.zeros(12))
        np.testing.assert_array_equal(task.start, START)
        index = [int(np.argmin(np.linalg.norm(points - p, axis=1)))
                 for p in task.poses[:, :3, 3]]
        np.testing.assert_allclose(points[index], task.poses[:, :3, 3], atol=1e-12)
        way = (np.diff(index) % len(points))
        assert set(way.tolist()) in ({1}, {len(points) - 1})  # neighbours, one way round
        leans = np.arccos(np.clip(-task.poses[:, 2, 2], -1.0, 1.0))  # the z axis from down
        assert np.ptp(leans) < 1e-9  # one chamfer angle a pass
        assert CHAMFER_RANGE[0] - 1e-9 <= leans[0] <= CHAMFER_RANGE[1] + 1e-9


def test_a_chain_is_found_only_where_the_arm_can_follow():
    arm = make_arm("kuka_kr6_r700")
    points, normals, tangents = rim_samples()
    poses = rim_poses(points[:8], normals[:8], tangents[:8], math.radians(45.0))
    start = np.array(START)
    chain = followable_chain(arm, start, poses, everywhere_free, all_paths_free)
    assert chain is not None and chain.shape == (8, 6)
    np.testing.assert_allclose(arm.fk(chain), poses, atol=1e-9)
    closed = arm.branch_closed_form
    rows = []
    for pose, q in zip(poses, chain, strict=True):
        candidates, valid = arm.ik(pose)
        gaps = np.where(valid, np.abs(candidates - q).max(axis=1), np.inf)
        assert gaps.min() < 1e-9
        rows.append(int(np.argmin(gaps)))
    assert len({int(closed[k]) for k in rows}) == 1  # one configuration
    assert np.abs(np.diff(chain, axis=0)).max() <= math.radians(30.0)
    # Nothing follows when no step may exceed 0.01° or no configuration is free.
    assert followable_chain(arm, start, poses, everywhere_free, all_paths_free,
                            limit=math.radians(0.01)) is None
    assert followable_chain(arm, start, poses, lambda q, need=None: np.zeros(len(q), bool),
                            all_paths_free) is None
    # A waypoint with no free candidate ends the search before any path is checked.
    last = arm.ik(poses[-1])[0]
    last = last[np.isfinite(last).all(axis=1)]

    def free_but_the_last_waypoint(q, need=None):
        return ~(np.abs(q[:, None, :] - last[None]).max(axis=2) == 0.0).any(axis=1)

    def no_path_check(q0, q1):
        raise AssertionError("a path was checked")

    assert followable_chain(arm, start, poses, free_but_the_last_waypoint,
                            no_path_check) is None


def _oracle_pass(env, oracle, obs, info) -> tuple[list[int], dict]:
    """The actions of one episode the DP oracle plays from ``obs``, ``info``; its last info."""
    done, actions = False, []
    while not done:
        action = int(oracle.predict(obs, action_masks=info["action_mask"])[0])
        actions.append(action)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    return actions, info


def test_the_deburring_id_plans_the_pass_in_one_configuration_with_the_spin():
    """The DP oracle finishes every pass without a collision and keeps one configuration
    within 30° steps; the burr's spin is part of what it chooses."""
    env = gym.make(ID)
    base = env.unwrapped
    oracle = make_baseline("dp_oracle", env)
    spins = set()
    for seed in range(3):
        actions, info = _oracle_pass(env, oracle, *env.reset(seed=seed))
        assert info["is_success"]
        closed = base.arm.branch_closed_form[actions]
        assert len(set(closed.tolist())) == 1
        spins |= {float(base.arm.branch_angles[a]) for a in actions}
    assert len(spins) > 1


def _masked_steps(env_id: str, seeds: range, **kwargs) -> list[float]:
    """The largest revolute step (rad) of every move inside the pass that the mask offers,
    along episodes of the first offered branch; each reset's ladder checked against the
    pricer's own (solved pose by pose, margins and continuity applied there)."""
    env = gym.make(env_id, **kwargs)
    base = env.unwrapped
    revolute = base.arm.revolute_mask
    steps = []
    for seed in seeds:
        _, info = env.reset(seed=seed)
        ladder = base.ladder
        own = base.pricer.task(ladder.task)
        np.testing.assert_array_equal(ladder.candidates, own.candidates)
        np.testing.assert_array_equal(ladder.valid, own.valid)
        np.testing.assert_array_equal(ladder.endpoint_collision, own.endpoint_collision)
        np.testing.assert_array_equal(ladder.inside, own.inside)
        assert ladder.limit == own.limit
        done, waypoint, q = False, 0, None
        while not done:
            offered = np.flatnonzero(info["action_mask"])
            if waypoint > 0:  # inside the pass: from the branch taken to each offered one
                moves = np.abs(ladder.candidates[waypoint, offered] - q)[:, revolute]
                steps += moves.max(axis=1).tolist()
            q = ladder.candidates[waypoint, offered[0]]
            _, _, terminated, truncated, info = env.step(int(offered[0]))
            done, waypoint = terminated or truncated, waypoint + 1
    return steps


def test_the_pass_offers_no_move_that_reconfigures_the_arm():
    """A reset solves its waypoints in one batched call; the ladder it makes applies the
    pass's step limit as the pricer's own does, so inside the pass every offered move
    stays within 30° on every joint. KukaKR6Deburring-v0 names no limit (its resets never
    applied one): there the mask offers reconfigurations."""
    assert max(_masked_steps(ID, range(3))) <= math.radians(30.0)
    assert max(_masked_steps("IKBranch/KukaKR6Deburring-v0", range(3))) > math.radians(90.0)


def test_a_batched_reset_leaves_out_the_branches_near_a_singularity():
    """The singularity margins apply to a batched reset's ladder as to the pricer's own."""
    margin = math.radians(25.0)
    env = gym.make(ID, singularity_margin=margin)
    base = env.unwrapped
    left_out = 0
    for seed in range(10):
        env.reset(seed=seed)
        plain = gym.make(ID).unwrapped
        plain.reset(seed=seed)
        assert np.array_equal(plain.ladder.task.poses, base.ladder.task.poses)
        left_out += int((plain.ladder.valid & ~base.ladder.valid).sum())
        own = base.pricer.task(base.ladder.task)
        np.testing.assert_array_equal(base.ladder.valid, own.valid)
        np.testing.assert_array_equal(base.ladder.candidates, own.candidates)
    assert left_out > 0


def test_a_pass_drawn_under_wide_singularity_margins_keeps_a_branch_outside_them():
    """At 40° the margins leave most drawn passes with a waypoint whose every branch lies
    inside them; the generator builds its chain on branches outside them only, so every
    reset keeps such a branch at each waypoint and the DP oracle still finishes the pass
    in one configuration."""
    margin = math.radians(40.0)
    env = gym.make(ID, singularity_margin=margin)
    base = env.unwrapped
    oracle = make_baseline("dp_oracle", env)
    for seed in range(8):
        obs, info = env.reset(seed=seed)
        valid = base.ladder.valid
        assert valid.any(axis=1).all()
        margins = singularity_margins(base.arm, base.ladder.candidates[valid])
        assert (margins.wrist >= margin).all() and (margins.elbow >= margin).all()
        if seed < 2:
            actions, info = _oracle_pass(env, oracle, obs, info)
            assert info["is_success"]
            assert len(set(base.arm.branch_closed_form[actions].tolist())) == 1


@pytest.mark.parametrize("degrees", [20.0, 11.5])
def test_a_pass_is_drawn_followable_within_the_envs_own_step_limit(degrees):
    """An env whose step limit is tighter than the ids' 30° draws passes the arm can follow
    within it (searched at 30°, half the resets at 20° had found no such chain), and the
    DP oracle follows one in one configuration with every inside step within it."""
    limit = math.radians(degrees)
    env = gym.make(ID, max_joint_step=limit)
    base = env.unwrapped
    revolute = np.asarray(base.arm.revolute_mask)
    for seed in range(6):
        env.reset(seed=seed)
        assert base.ladder.valid.any(axis=1).all()
    oracle = make_baseline("dp_oracle", env)
    actions, info = _oracle_pass(env, oracle, *env.reset(seed=0))
    assert info["is_success"]
    configurations = base.ladder.candidates[np.arange(len(actions)), actions]
    steps = np.abs(np.diff(configurations, axis=0))[:, revolute]
    assert steps.max() <= limit


def test_a_step_limit_no_pass_can_keep_is_refused_with_the_limit_named():
    """5.7°: none of the 200 passes drawn keeps within it (a corner sample turns the burr
    by 15°); the error names the limit."""
    env = gym.make(ID, max_joint_step=0.1)
    with pytest.raises(RuntimeError, match=r"joint steps of at most 5\.73°"):
        env.reset(seed=0)
