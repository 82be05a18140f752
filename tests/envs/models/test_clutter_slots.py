"""Per-episode clutter (``scene_seed=None``): new obstacles every reset, no recompile, the
same obstacles as the fixed scene of that seed, and collision checks that follow."""

from __future__ import annotations

import pickle

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import ikbranch_gym.envs  # noqa: F401
from ikbranch_gym.envs.models import CollisionChecker, build_model, candidate_pairs
from ikbranch_gym.envs.seeds import HELD_OUT_SCENES, TRAIN_SCENES

ARMS = ("anthropomorphic", "cylindrical", "kuka_kr6_r700")


def _env(arm: str, **kwargs):
    return gym.make("IKBranch/Anthropomorphic-v3", arm=arm, n_waypoints=3, **kwargs).unwrapped


@pytest.mark.parametrize("arm_name", ARMS)
def test_each_scene_is_the_fixed_scene_of_its_seed(arm_name):
    # Same obstacles as build_model(..., seed=s): the same verdicts everywhere (the boxes
    # are primitives here and meshes there; the clearance test below checks both against
    # the exact distance).
    env = _env(arm_name)
    arm = env.arm
    rng = np.random.default_rng(0)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(800, arm.dof))
    for seed in (0, 5, 11):
        env._lay_scene(seed)
        fixed = CollisionChecker(build_model(arm_name, "random_clutter", seed=seed), dof=arm.dof,
                                 backend="loop")
        laid = CollisionChecker(env.model, dof=arm.dof, backend="loop")
        np.testing.assert_array_equal(laid.collides(q), fixed.collides(q))
        np.testing.assert_array_equal(env.checker.collides(q), fixed.collides(q))


@pytest.mark.parametrize("arm_name", ARMS)
def test_compiled_checks_follow_the_obstacles(arm_name):
    env = _env(arm_name)
    arm, checker = env.arm, env.checker
    rng = np.random.default_rng(1)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    q0 = rng.uniform(lower, upper, size=(600, arm.dof))
    q1 = np.clip(q0 + rng.uniform(-0.25, 0.25, size=q0.shape) * (upper - lower), lower, upper)
    hits = []
    for seed in (3, 4, 9):
        env._lay_scene(seed)
        loop = CollisionChecker(env.model, dof=arm.dof, backend="loop")
        expected = loop.check_paths(q0, q1)
        np.testing.assert_equal(checker.check_paths(q0, q1), expected)
        np.testing.assert_array_equal(checker.paths_collide(q0, q1), expected[0])
        np.testing.assert_array_equal(checker.n_contacts(q0), loop.n_contacts(q0))
        hits.append(expected[0])
    assert not np.array_equal(hits[0], hits[1])  # the scenes differ


def test_clearance_verdict_is_the_exact_distance_with_primitive_obstacles():
    env = _env("anthropomorphic")
    arm = env.arm
    rng = np.random.default_rng(2)
    for seed in (1, 2):
        env._lay_scene(seed)
        model = env.checker.model  # margins set: the checker's own copy
        data = mujoco.MjData(model)
        pairs = candidate_pairs(model)
        q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(150, arm.dof))
        for row, verdict in zip(q, env.checker.collides(q), strict=True):
            data.qpos[: arm.dof] = row
            mujoco.mj_kinematics(model, data)
            nearest = min(mujoco.mj_geomDistance(model, data, a, b, 1.0, None) for a, b in pairs)
            if abs(nearest - env.checker.resolution) > 1e-6:
                assert verdict == (nearest < env.checker.resolution)


def test_resets_draw_scenes_without_recompiling_and_deterministically():
    env = gym.make("IKBranch/Anthropomorphic-v2")
    base = env.unwrapped
    model = base.model
    seeds = [env.reset(seed=s)[1]["scene_seed"] for s in range(6)]
    assert len(set(seeds)) == 6 and all(TRAIN_SCENES[0] <= s < TRAIN_SCENES[1] for s in seeds)
    assert base.model is model
    _, info = env.reset(seed=2)
    layout = base.model.geom_pos.copy()
    task = base.task
    _, again = env.reset(seed=2)
    assert again["scene_seed"] == info["scene_seed"] == seeds[2]
    np.testing.assert_array_equal(base.model.geom_pos, layout)
    np.testing.assert_array_equal(base.task.poses, task.poses)
    copy = pickle.loads(pickle.dumps(base))  # the scene travels with the env
    assert copy.scene_seed == base.scene_seed
    np.testing.assert_array_equal(copy.model.geom_pos, base.model.geom_pos)


def test_held_out_scenes_come_from_their_own_range():
    assert TRAIN_SCENES[1] <= HELD_OUT_SCENES[0]  # disjoint
    env = gym.make("IKBranch/Anthropomorphic-v2", scene_seeds=list(HELD_OUT_SCENES))
    drawn = [env.reset(seed=s)[1]["scene_seed"] for s in range(20)]
    assert all(HELD_OUT_SCENES[0] <= s < HELD_OUT_SCENES[1] for s in drawn)
    with pytest.raises(ValueError, match="scene_seeds"):
        gym.make("IKBranch/Anthropomorphic-v2", scene_seeds=[5, 5])
    # A scene without clutter has nothing to draw: the seed is ignored there, as 0 is.
    assert gym.make("IKBranch/ToolTransfer-v1", scene_seed=None).unwrapped._clutter is None


def test_a_new_scene_forgets_the_old_verdicts():
    env = _env("anthropomorphic")
    arm, pricer = env.arm, env.pricer
    rng = np.random.default_rng(4)
    q0, q1 = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(2, 400, arm.dof))
    env._lay_scene(7)
    first = pricer.paths_collide(q0, q1)  # now cached
    env._lay_scene(8)
    second = pricer.paths_collide(q0, q1)
    np.testing.assert_array_equal(second, env.checker.paths_collide(q0, q1))
    assert not np.array_equal(first, second)


def test_parked_slots_are_skipped_and_come_back_when_laid():
    # A parked slot (100 m below) is beyond every arm geom's reach: its pairs are marked
    # OUT_OF_REACH and skipped; laid again, they are checked again.
    from ikbranch_gym.envs.models.filter.layout import OUT_OF_REACH

    env = _env("anthropomorphic")
    scene = env.checker._filter.scene
    slots = env._clutter.geoms
    in_slots = np.isin(scene.slot_geom[scene.pair_b], slots)
    for seed in range(40):
        env._lay_scene(seed)
        parked = env.model.geom_pos[slots, 2] < -50.0
        if parked.any() and not parked.all():
            break
    else:
        pytest.fail("no scene with both parked and laid slots")
    parked_geoms = slots[parked]
    skipped = scene.pair_kind[0] == OUT_OF_REACH  # the filter's one scene
    of_parked = np.isin(scene.slot_geom[scene.pair_b], parked_geoms)
    assert skipped[of_parked].all() and of_parked.any()
    assert not skipped[in_slots & ~of_parked].any()  # the laid ones stay near the arm
    assert not skipped[~in_slots].any()  # the fixed scene is never skipped


@pytest.mark.parametrize("arm_name", ARMS)
def test_a_refreshed_filter_equals_one_compiled_for_the_laid_scene(arm_name):
    # refresh_static re-reads only the obstacle slots; a scene compiled afresh from the
    # laid model reads everything (static frames from MuJoCo's own kinematics).
    from ikbranch_gym.envs.models.filter import compile_scene

    env = _env(arm_name)
    checker = env.checker
    scene = checker._filter.scene
    for seed in (0, 5, 11, 23):
        env._lay_scene(seed)
        fresh = compile_scene(checker.model, env.arm.dof, checker._pairs)
        # (pair_kind: a fresh scene does not skip parked slots; the test above covers that.)
        for name in ("slot_type", "pair_kind_own", "slot_size", "slot_radius", "slot_geom",
                     "slot_inner", "slot_inner_size", "pair_contact", "pair_lever"):
            np.testing.assert_array_equal(getattr(scene, name), getattr(fresh, name), name)
        for name in ("slot_pos", "slot_rot", "pair_fixed", "pair_reach"):
            np.testing.assert_allclose(getattr(scene, name), getattr(fresh, name),
                                       rtol=0, atol=1e-12, err_msg=name)
    # Without a list, every static geom is read again (here: after wiping them all).
    # (Per-scene arrays: the filter's one scene is row 0.)
    names = ("slot_pos", "slot_rot", "slot_radius", "slot_inner_size", "pair_reach")
    refreshed = {name: getattr(scene, name)[0].copy() for name in names}
    static = np.flatnonzero(scene.slot_static)
    for name in names[:-1]:
        getattr(scene, name)[0, static] = 0.0
    scene.pair_reach[:] = 0.0
    checker.refresh_static()
    with_static = scene.slot_static[scene.pair_b]  # the pairs a static geom's refresh sets
    assert with_static.any()
    for name, values in refreshed.items():
        if name == "pair_reach":
            values, now = values[with_static], scene.pair_reach[0, with_static]
        else:
            now = getattr(scene, name)[0]
        np.testing.assert_array_equal(now, values, err_msg=name)


def test_a_slot_that_changes_its_kind_is_refused():
    env = _env("anthropomorphic")
    checker = env.checker
    box = int(env._clutter.ids[0, 0])
    checker.model.geom_type[box] = mujoco.mjtGeom.mjGEOM_SPHERE
    with pytest.raises(ValueError, match=r"clutter0_box.*changed its kind"):
        checker.refresh_static(env._clutter.geoms)
