"""The compiled filter's answers are MuJoCo's.

The exactness tests compare the ``"compiled"`` backend with ``"loop"`` (the advancing
Python loop, itself tested equal to checking every grid sample in test_collision.py) and
demand equality: the same verdict and the same first colliding sample for every path, the
same contact count for every configuration.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import CollisionChecker, arm_spec, build_model
from ikbranch_gym.envs.models.builders import add_part, add_static_body, compile_spec
from ikbranch_gym.envs.models.filter import COUNTERS
from ikbranch_gym.envs.models.filter.kernels import LANE_FUNCTION, LANE_PATHS
from tests.envs.models.conftest import scene_cases

#: Paths per arm × scene in the exactness tests (half short moves, half across the range).
PATHS = 2000


def _checker(arm_name: str, scene: str, backend: str, **kwargs) -> CollisionChecker:
    arm = make_arm(arm_name)
    return CollisionChecker(build_model(arm_name, scene, **kwargs), dof=arm.dof, backend=backend)


def _without_lanes(checker: CollisionChecker) -> CollisionChecker:
    """``checker`` with its filter's lanes switched off: the scalar kernel alone, as on a
    machine without a C compiler."""
    checker._filter._exact[0, LANE_FUNCTION] = 0
    checker._filter._exact[0, LANE_PATHS] = 0
    return checker


def _paths(arm, rng, count, reach=0.25):
    """Half: from uniform configurations by up to ``reach`` of every joint range; half:
    between two uniform configurations."""
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    q0 = rng.uniform(lower, upper, size=(count, arm.dof))
    near = np.clip(q0 + rng.uniform(-reach, reach, size=q0.shape) * (upper - lower), lower,
                   upper)
    far = rng.uniform(lower, upper, size=q0.shape)
    q1 = np.where(np.arange(count)[:, None] % 2 == 0, near, far)
    return q0, q1



# ------------------------------------------------------------------------- exactness
@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_path_verdicts_and_first_samples_equal_the_loop(arm_name, scene):
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    compiled = CollisionChecker(model, dof=arm.dof, backend="compiled")
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    q0, q1 = _paths(arm, np.random.default_rng(20), PATHS)
    collides, first = loop.check_paths(q0, q1)
    np.testing.assert_array_equal(compiled.paths_collide(q0, q1), collides)
    fast_collides, fast_first = compiled.check_paths(q0, q1)
    np.testing.assert_array_equal(fast_collides, collides)
    np.testing.assert_array_equal(fast_first, first)  # NaN == NaN for free paths
    if arm_name != "rod_mechanism":  # the rod's table stays clear of itself and the clutter
        assert 0.02 < collides.mean() < 0.98  # both verdicts are exercised
    # One start, many ends (a step's K moves) is the same check.
    from_one = loop.check_paths(np.broadcast_to(q0[0], q1[:50].shape), q1[:50])[0]
    np.testing.assert_array_equal(compiled.paths_collide(q0[0], q1[:50]), from_one)


@pytest.mark.parametrize("arm_name", ["anthropomorphic", "cartesian", "ur5e"])
def test_without_lanes_the_scalar_kernel_alone_answers_as_the_loop(arm_name):
    # Every arm has lanes; a machine without a C compiler has none: the same answers.
    arm = make_arm(arm_name)
    model = build_model(arm_name, "random_clutter")
    compiled = _without_lanes(CollisionChecker(model, dof=arm.dof, backend="compiled"))
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    rng = np.random.default_rng(23)
    q0, q1 = _paths(arm, rng, PATHS // 2, reach=0.25 if arm_name != "ur5e" else 0.02)
    collides, first = loop.check_paths(q0, q1)
    fast_collides, fast_first = compiled.check_paths(q0, q1)
    np.testing.assert_array_equal(fast_collides, collides)
    np.testing.assert_array_equal(fast_first, first)
    np.testing.assert_array_equal(compiled.paths_collide(q0, q1), collides)
    np.testing.assert_array_equal(compiled.n_contacts(q0), loop.n_contacts(q0))
    lanes = compiled._filter.counters[COUNTERS.index("lane samples")]
    assert lanes == 0 and 0.05 < collides.mean() < 0.95


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_configuration_counts_and_verdicts_equal_the_loop(arm_name, scene):
    # Counts are always MuJoCo's own; verdicts may come from inner shapes (witnesses)
    # instead of MuJoCo: the same verdicts.
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    compiled = CollisionChecker(model, dof=arm.dof, backend="compiled")
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    rng = np.random.default_rng(21)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(PATHS, arm.dof))
    counts = loop.n_contacts(q)
    np.testing.assert_array_equal(compiled.n_contacts(q), counts)
    assert compiled.n_contacts(q.reshape(2, -1, arm.dof)).shape == (2, PATHS // 2)
    before = compiled._filter.counters.copy()
    np.testing.assert_array_equal(compiled.collides(q), counts > 0)
    spent = dict(zip(COUNTERS, compiled._filter.counters - before, strict=True))
    witnessed = spent["witnessed"] + spent["lane contacts"]  # the scalar kernel's, the lanes'
    if (counts > 0).sum() >= 10:  # most contacts need no MuJoCo call
        assert witnessed > 0.5 * (counts > 0).sum()


@pytest.mark.parametrize("backend", ["compiled", "loop"])
def test_first_free_rows_are_the_full_checks_first_free_rows(backend):
    arm = make_arm("anthropomorphic")
    checker = _checker("anthropomorphic", "random_clutter", backend)
    rng = np.random.default_rng(22)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(400, arm.dof))
    free = np.flatnonzero(~checker.collides(q))
    assert 20 < len(free) < 380
    for need in (1, 2, 5, len(free), len(free) + 3):
        np.testing.assert_array_equal(checker.first_free_rows(q, need), free[:need])
    if backend == "compiled":  # the rows after the need-th free one are not checked
        _without_lanes(checker)  # (the lanes bound four rows a wanted one at once)
        before = checker._filter.counters[0]
        checker.first_free_rows(q, 1)
        assert checker._filter.counters[0] - before == free[0] + 1


def test_milling_cell_transfers_equal_the_loop():
    arm = make_arm("anthropomorphic")
    model = build_model("anthropomorphic", "milling_cell")
    from ikbranch_gym.envs.models import milling_cell_poses

    (q1, ok1), (q2, ok2) = (arm.ik(pose) for pose in milling_cell_poses())
    assert ok1.all() and ok2.all()
    compiled = CollisionChecker(model, dof=arm.dof, backend="compiled")
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    expected = loop.check_paths(q1[:, None], q2[None])
    np.testing.assert_equal(compiled.check_paths(q1[:, None], q2[None]), expected)
    np.testing.assert_array_equal(compiled.paths_collide(q1[:, None], q2[None]), expected[0])
    assert expected[0].sum() == 61  # docs/models.md: 3 of the 64 transfers are free
    result = compiled.check_path(q1[0], q2[0])
    assert not result.collides and result.n_samples == loop.check_path(q1[0], q2[0]).n_samples


def test_thin_obstacle_and_tilted_plane_equal_the_loop():
    # A 4 mm rod across the tool's sweep and a tilted wall: the shapes where a filter
    # that only looked at samples, or at a level floor, would go wrong.
    arm = make_arm("anthropomorphic")
    spec, _ = arm_spec(arm, tool=True)
    q = arm.home.copy()
    q[0] = np.radians(2.5)
    pose = arm.fk(q)
    middle = pose[:3, 3] + 0.2 * pose[:3, 1]
    add_part(add_static_body(spec, "rod"), "rod", "capsule", [0.002], (1, 0, 0, 1),
             fromto=[middle[0], middle[1], 0.05, middle[0], middle[1], middle[2] + 0.05])
    wall = spec.worldbody.add_geom()
    wall.name, wall.type = "wall", mujoco.mjtGeom.mjGEOM_PLANE
    wall.size, wall.pos = [0.0, 0.0, 0.05], [1.2, 0.0, 1.0]
    wall.quat = [np.cos(0.6), 0.0, -np.sin(0.6), 0.0]
    model = compile_spec(spec)
    compiled = CollisionChecker(model, dof=arm.dof, backend="compiled")
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    q0, q1 = arm.home.copy(), arm.home.copy()
    q0[0], q1[0] = np.radians(-30.0), np.radians(30.0)
    assert compiled.check_path(q0, q1) == loop.check_path(q0, q1)
    assert compiled.check_path(q0, q1).collides
    starts, ends = _paths(arm, np.random.default_rng(22), 400)
    np.testing.assert_equal(compiled.check_paths(starts, ends), loop.check_paths(starts, ends))


def test_unpadded_checks_equal_the_loop():
    # pad=False: margins 0, so "collision" means touching; the bounds must follow.
    arm = make_arm("anthropomorphic")
    model = build_model("anthropomorphic", "random_clutter", seed=3)
    compiled = CollisionChecker(model, dof=arm.dof, pad=False, backend="compiled")
    loop = CollisionChecker(model, dof=arm.dof, pad=False, backend="loop")
    q0, q1 = _paths(arm, np.random.default_rng(23), 400)
    np.testing.assert_equal(compiled.check_paths(q0, q1), loop.check_paths(q0, q1))
    np.testing.assert_array_equal(compiled.n_contacts(q0), loop.n_contacts(q0))


def test_the_filter_decides_most_samples_itself():
    # The point of the filter: on random-clutter paths MuJoCo sees a small share of the
    # grid samples (a regression of the bounds shows up here before it shows in speed).
    arm = make_arm("anthropomorphic")
    checker = _checker("anthropomorphic", "random_clutter", "compiled", seed=1)
    q0, q1 = _paths(arm, np.random.default_rng(24), 300)
    grid = int((checker.n_steps(q0, q1) + 1).sum())
    checker.paths_collide(q0, q1)
    spent = dict(zip(COUNTERS, checker._filter.counters, strict=True))
    assert spent["mujoco"] < 0.01 * grid
    assert spent["bounded"] + spent["lane samples"] < 0.1 * grid



def test_mujoco_checks_that_find_no_contact_are_counted():
    # An ellipsoid is bounded by its box, whose corners stick out: samples there go to
    # MuJoCo and come back free (false alarms). Every colliding sample is either proven in
    # contact by inner shapes (witnessed) or confirmed by MuJoCo, so those two add up to
    # the colliding configurations, and to one per colliding path in a verdict-only call.
    arm = make_arm("anthropomorphic")
    spec, _ = arm_spec(arm)
    egg = add_static_body(spec, "egg").add_geom()
    egg.name, egg.type = "egg", mujoco.mjtGeom.mjGEOM_ELLIPSOID
    egg.size, egg.pos = [0.35, 0.35, 0.35], [0.9, 0.0, 1.0]
    checker = CollisionChecker(compile_spec(spec), dof=arm.dof, backend="compiled")
    counters = checker._filter.counters
    rng = np.random.default_rng(25)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(3000, arm.dof))
    before = counters.copy()
    colliding = checker.collides(q)
    spent = dict(zip(COUNTERS, counters - before, strict=True))
    checks, alarms, witnessed = spent["mujoco"], spent["mujoco found free"], spent["witnessed"]
    assert colliding.any() and alarms > 0 and witnessed > 0
    assert checks - alarms + witnessed + spent["lane contacts"] == colliding.sum()
    q0, q1 = _paths(arm, np.random.default_rng(26), 400)
    before = counters.copy()
    hits = checker.paths_collide(q0, q1)
    spent = dict(zip(COUNTERS, counters - before, strict=True))
    checks, alarms, witnessed = spent["mujoco"], spent["mujoco found free"], spent["witnessed"]
    assert hits.any() and alarms > 0 and witnessed > 0
    assert checks - alarms + witnessed + spent["lane contacts"] == hits.sum()


@pytest.mark.parametrize(("arm_name", "lanes"), [("anthropomorphic", False), ("ur5e", True)])
def test_a_stack_checks_every_scene_as_its_own_filter(arm_name, lanes):
    # Three clutters of one model in one stack: each row and path, tagged with its scene,
    # gets the verdict and first sample of that scene's own checker; a clutter laid in one
    # member afterwards is what the stack checks too.
    from ikbranch_gym.envs.models.filter import FilterStack, path_steps
    from ikbranch_gym.envs.models.scenes import CLUTTER_SLOTS, ClutterSlots, draw_clutter

    arm = make_arm(arm_name)
    checkers, slots = [], []
    for _ in range(3):
        model = build_model(arm_name, "random_clutter", seed=None)
        checker = CollisionChecker(model, dof=arm.dof)
        if not lanes:
            _without_lanes(checker)
        clutter = ClutterSlots(checker.model, CLUTTER_SLOTS)
        checkers.append(checker)
        slots.append(clutter)
    references = [CollisionChecker(checker.model, dof=arm.dof, backend="loop")
                  for checker in checkers]

    def lay(i, seed):
        slots[i].lay(draw_clutter(arm, seed, slots[i].base, CLUTTER_SLOTS), checkers[i].model,
                     references[i].model)
        checkers[i].refresh_static(slots[i].geoms)
        references[i].refresh_static(slots[i].geoms)

    for i, seed in enumerate((3, 4, 5)):
        lay(i, seed)
    stack = FilterStack([checker._filter for checker in checkers])
    rng = np.random.default_rng(33)
    # UR5e's joints turn ±2π: its moves across a quarter of that nearly all collide.
    q0, q1 = _paths(arm, rng, 600, reach=0.25 if arm_name == "anthropomorphic" else 0.02)
    scenes = rng.integers(3, size=600)
    for relaid in (False, True):
        if relaid:
            lay(1, 9)
        steps = np.empty(600, dtype=np.int64)
        path_steps(q0, q1, checkers[0].lever, checkers[0].resolution, steps)
        first = stack.paths(scenes, q0, q1, steps, True)
        verdicts = stack.collide(scenes, q0) > 0
        for i in range(3):
            mine = scenes == i
            expected, fraction = references[i].check_paths(q0[mine], q1[mine])
            np.testing.assert_array_equal(first[mine] >= 0, expected)
            hit = expected
            np.testing.assert_array_equal(first[mine][hit] / steps[mine][hit], fraction[hit])
            np.testing.assert_array_equal(verdicts[mine], references[i].collides(q0[mine]))
            assert 0.05 < expected.mean() < 0.95


def test_witnessed_configurations_are_mujocos_contacts_and_cylinders_prove_their_own():
    # Through the kernel (kernels._witnessed): every configuration a witness decided is
    # one MuJoCo finds in contact, and on UR5e in clutter (the flange and the clutter's
    # posts are cylinders) many of them no pair of inner shapes could prove: the cylinder
    # pass proved them, each side taking the other's cylinder as itself.
    from ikbranch_gym.envs.models.filter import kernels, shapes
    from ikbranch_gym.envs.models.filter import tree as kinematics

    arm = make_arm("ur5e")
    checker = _checker("ur5e", "random_clutter", "compiled", seed=3)
    model, data = checker.model, mujoco.MjData(checker.model)
    scene = checker._filter.scene
    rng = np.random.default_rng(25)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(3000, arm.dof))
    _, how = checker._filter.collide_how(q)
    geometry = kernels._scene(scene.geometry, 0)
    (slot_body, slot_static, slot_pos, slot_rot, _, _, _, pair_a, pair_b, _, _, _, _, _, _,
     slot_inner, slot_inner_size, pair_contact, pair_skewer) = geometry
    xpos, xmat, wpos, wrot, _, _ = kernels._work(scene.tree, scene.geometry)
    kernels._enter(geometry, wpos, wrot)
    cylinder_only = 0
    for row in np.flatnonzero(how == kernels.BY_WITNESS):
        qpos = model.qpos0.copy()
        qpos[: arm.dof] = q[row]
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        assert data.ncon > 0, row
        kinematics._forward(*scene.tree[:12], qpos, xpos, xmat)
        kinematics._place_slots(slot_body, slot_static, slot_pos, slot_rot, xpos, xmat, wpos,
                                wrot)
        inner_pair = False
        for k in np.flatnonzero(np.isfinite(pair_contact)):
            a, b = pair_a[k], pair_b[k]
            args = (slot_inner[a], kernels._centre(wpos, a), kernels._rotation(wrot, a),
                    kernels._size(slot_inner_size, a), slot_inner[b], kernels._centre(wpos, b),
                    kernels._rotation(wrot, b), kernels._size(slot_inner_size, b))
            if shapes._inner_distance(*args) < pair_contact[k] and not (
                    pair_skewer[k] and shapes._skewers(*args)):
                inner_pair = True
                break
        cylinder_only += not inner_pair
    assert (how == kernels.BY_WITNESS).sum() > 500
    assert cylinder_only > 20
