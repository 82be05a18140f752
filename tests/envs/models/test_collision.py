"""Collision checks: configurations, paths, the resolution guarantee, batch vs loop."""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import ARM_NAMES, make_arm
from ikbranch_gym.envs.models import CollisionChecker, arm_spec, build_model
from ikbranch_gym.envs.models.builders import add_part, add_static_body, compile_spec
from ikbranch_gym.envs.models.collision import candidate_pairs
from tests.envs.models.conftest import TWO_ARM_NAMES, scene_cases


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_home_is_collision_free(arm_name, scene):
    arm = make_arm(arm_name)
    checker = CollisionChecker(build_model(arm_name, scene), dof=arm.dof)
    assert checker.contacts(arm.home) == ()
    assert not checker.collides(arm.home)


def _rod_model(phi1_hit: float, radius: float):
    """The anthropomorphic arm (with tool) and a thin vertical rod standing where the tool
    passes when φ1 = ``phi1_hit`` (all other joints at home)."""
    arm = make_arm("anthropomorphic")
    spec, _ = arm_spec(arm, tool=True)
    q = arm.home.copy()
    q[0] = phi1_hit
    pose = arm.fk(q)
    middle = pose[:3, 3] + 0.2 * pose[:3, 1]  # a point on the tool axis
    rod = add_static_body(spec, "rod")
    add_part(rod, "rod", "capsule", [radius], (1, 0, 0, 1),
             fromto=[middle[0], middle[1], 0.05, middle[0], middle[1], middle[2] + 0.05])
    return arm, spec.compile()


def _sweep(arm, start_deg, end_deg):
    q0, q1 = arm.home.copy(), arm.home.copy()
    q0[0], q1[0] = np.radians(start_deg), np.radians(end_deg)
    return q0, q1


def test_thin_rod_missed_by_coarse_samples_is_caught():
    # Samples every 5° at −30°, −25°, … and a 4 mm rod hit at 2.5°, half-way between two.
    arm, model = _rod_model(np.radians(2.5), radius=0.002)
    q0, q1 = _sweep(arm, -30.0, 30.0)
    coarse = q0 + np.linspace(0.0, 1.0, 13)[:, None] * (q1 - q0)
    exact = CollisionChecker(model, dof=arm.dof, pad=False)
    assert not exact.collides(coarse).any()  # what "check the samples" alone would say

    checker = CollisionChecker(model, dof=arm.dof)
    result = checker.check_path(q0, q1)
    assert result.collides
    assert ("rod", "tool") in result.pairs or ("tool", "rod") in result.pairs
    # The tool reaches the rod before φ1 = 2.5°, but no more than a tool radius plus the
    # clearance ahead of it (~0.03 m at ~2 m from the axis, i.e. about 1°).
    hit_fraction = (2.5 + 30.0) / 60.0
    assert hit_fraction - 2.0 / 60.0 < result.first_fraction < hit_fraction
    assert result.n_samples > 13


def test_sampling_certificate_against_a_dense_exact_check():
    # Any path the checker calls free has no contact at 20× denser exact samples.
    arm, model = _rod_model(np.radians(10.0), radius=0.002)
    checker = CollisionChecker(model, dof=arm.dof)
    exact = CollisionChecker(model, dof=arm.dof, pad=False)
    rng = np.random.default_rng(5)
    free = 0
    for _ in range(20):
        q0 = arm.home + rng.normal(scale=0.15, size=arm.dof)
        q1 = arm.home + rng.normal(scale=0.15, size=arm.dof)
        q0[0], q1[0] = rng.uniform(-0.3, 0.5, size=2)
        if not checker.check_path(q0, q1).collides:
            free += 1
            n = 20 * int(checker.n_steps(q0, q1))
            dense = q0 + np.linspace(0.0, 1.0, n + 1)[:, None] * (q1 - q0)
            assert not exact.collides(dense).any()
    assert free > 0


def test_free_path_and_its_endpoints():
    arm, model = _rod_model(np.radians(90.0), radius=0.05)
    checker = CollisionChecker(model, dof=arm.dof)
    q0, q1 = _sweep(arm, -30.0, 30.0)
    result = checker.check_path(q0, q1)
    assert not result.collides and np.isnan(result.first_fraction) and result.contacts == ()
    samples = checker.path_samples(q0, q1)
    np.testing.assert_array_equal(samples[0], q0)
    np.testing.assert_array_equal(samples[-1], q1)


def _bounding_sphere_points(model, xpos, xmat):
    """(…, ngeom, 7, 3): every geom's centre and the six points of its bounding sphere on
    its local axes, in world coordinates (the lever-arm bound covers the whole sphere), for
    geom placements ``xpos`` (…, ngeom, 3) and ``xmat`` (…, ngeom, 9)."""
    offsets = np.concatenate([np.zeros((1, 3)), np.eye(3), -np.eye(3)])
    local = model.geom_rbound[:, None, None] * offsets[None]
    rotation = xmat.reshape(*xmat.shape[:-1], 3, 3)
    return xpos[..., None, :] + np.einsum("...gij,gkj->...gki", rotation, local)


@pytest.mark.parametrize("arm_name", ARM_NAMES)
def test_step_respects_the_displacement_bound(arm_name):
    # The lever-arm bound really bounds how far geom points (centres and bounding-sphere
    # points) move between samples, hinges and slides mixed in any order.
    arm = make_arm(arm_name)
    model = build_model(arm_name, tool=True)
    checker = CollisionChecker(model, dof=arm.dof)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(11)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    for _ in range(20):
        q0, q1 = rng.uniform(lower, upper, size=(2, arm.dof))
        samples = checker.path_samples(q0, q1)
        xpos, xmat = [], []
        for q in samples:
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            xpos.append(data.geom_xpos.copy())
            xmat.append(data.geom_xmat.copy())
        positions = _bounding_sphere_points(model, np.array(xpos), np.array(xmat))
        moved = np.linalg.norm(np.diff(positions, axis=0), axis=-1).max()
        assert moved <= checker.resolution + 1e-12


@pytest.mark.parametrize("arm_name", TWO_ARM_NAMES)
def test_two_arm_contacts_count_but_not_each_arms_joints(arm_name):
    arm = make_arm(arm_name)
    checker = CollisionChecker(build_model(arm_name), dof=arm.dof)
    arm1 = {"base", *(f"link_{name}" for name in arm.joint_names[:3])}
    arm2 = {"base2", *(f"link_{name}" for name in arm.joint_names[3:])}
    chains = [
        ["base", *(f"link_{n}" for n in arm.joint_names[:3])],
        ["base2", *(f"link_{n}" for n in arm.joint_names[3:])],
    ]
    # Chain order is the physical one, which for RRP–RPP's arm 2 is not the joint order.
    model = checker.model
    for chain in chains:
        chain.sort(key=lambda body: model.body(body).id)
    adjacent = {frozenset(p) for chain in chains for p in itertools.pairwise(chain)}
    q = np.random.default_rng(4).uniform(
        arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(600, arm.dof)
    )
    between = 0
    for row in q[checker.collides(q)]:
        for contact in checker.contacts(row):
            pair = {contact.body1, contact.body2}
            assert frozenset(pair) not in adjacent
            between += bool(pair & arm1) and bool(pair & arm2)
    assert between > 0


def test_self_and_floor_contacts_are_reported_but_not_adjacent_links():
    arm = make_arm("anthropomorphic")
    model = build_model("anthropomorphic", tool=True)
    checker = CollisionChecker(model, dof=arm.dof)
    rng = np.random.default_rng(3)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(400, arm.dof))
    chain = ["base", *(f"link_{name}" for name in arm.joint_names)]
    adjacent = {frozenset(p) for p in itertools.pairwise(chain)}
    kinds = set()
    for row in q[checker.collides(q)]:
        for contact in checker.contacts(row):
            assert frozenset((contact.body1, contact.body2)) not in adjacent
            kinds.add("floor" if "world" in (contact.body1, contact.body2) else "self")
    assert kinds == {"floor", "self"}


def test_contact_bodies_are_the_bodies_of_the_contacts():
    # The clutter drops the obstacles touching the arm at home by these names.
    arm = make_arm("ur5e")
    checker = CollisionChecker(build_model("ur5e", "random_clutter"), dof=arm.dof)
    rng = np.random.default_rng(4)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(300, arm.dof))
    colliding = q[checker.collides(q)]
    assert len(colliding) > 20
    seen = set()
    for row in colliding[:60]:
        bodies = checker.contact_bodies(row)
        assert bodies == {name for c in checker.contacts(row) for name in (c.body1, c.body2)}
        seen |= bodies
    assert any(name.startswith("clutter") for name in seen)
    assert checker.contact_bodies(arm.home) == frozenset()


def test_batch_matches_loop_and_is_deterministic():
    arm = make_arm("anthropomorphic")
    model = build_model("anthropomorphic", "milling_cell")
    checker = CollisionChecker(model, dof=arm.dof, chunk=256, backend="batch")
    q = np.random.default_rng(1).uniform(
        arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(700, arm.dof)
    )
    batched = checker.collides(q)
    np.testing.assert_array_equal(batched, checker.collides_loop(q))
    np.testing.assert_array_equal(batched, checker.collides(q))
    assert 0 < batched.sum() < len(q)
    assert checker.collides(q.reshape(7, 100, arm.dof)).shape == (7, 100)


@pytest.mark.parametrize("backend", ["batch", "loop"])
def test_check_paths_matches_check_path(backend):
    arm = make_arm("anthropomorphic")
    model = build_model("anthropomorphic", "milling_cell")
    checker = CollisionChecker(model, dof=arm.dof, backend=backend)
    other = CollisionChecker(model, dof=arm.dof, backend="loop" if backend == "batch" else "batch")
    rng = np.random.default_rng(2)
    q0 = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(3, 1, arm.dof)) * 0.3
    q1 = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(1, 4, arm.dof)) * 0.3
    collides, first = checker.check_paths(q0, q1)
    assert collides.shape == first.shape == (3, 4)
    for i in range(3):
        for j in range(4):
            single = checker.check_path(q0[i, 0], q1[0, j])
            assert single.collides == collides[i, j]
            np.testing.assert_equal(single.first_fraction, first[i, j])
    np.testing.assert_equal(other.check_paths(q0, q1), (collides, first))


def test_bad_input_is_rejected():
    checker = CollisionChecker(build_model("cylindrical4"), dof=4)
    with pytest.raises(ValueError):
        checker.collides(np.zeros(3))
    with pytest.raises(ValueError):
        checker.collides(np.full(4, np.nan))
    with pytest.raises(ValueError):
        CollisionChecker(build_model("cylindrical4"), resolution=0.0)


# ------------------------------------------------------------ conservative advancement
def _short_paths(arm, rng, count):
    """Paths from random configurations by random joint moves of up to a quarter range."""
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    q0 = rng.uniform(lower, upper, size=(count, arm.dof))
    q1 = np.clip(q0 + rng.uniform(-0.25, 0.25, size=q0.shape) * (upper - lower), lower, upper)
    return q0, q1


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_advancing_loop_equals_the_flat_grid_check(arm_name, scene):
    # The loop backend skips samples it proves free; its verdicts and first colliding
    # samples must be exactly those of checking every grid sample (the batch backend).
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    flat = CollisionChecker(model, dof=arm.dof, backend="batch", nthread=1)
    q0, q1 = _short_paths(arm, np.random.default_rng(5), 40)
    collides, first = loop.check_paths(q0, q1)
    np.testing.assert_equal((collides, first), flat.check_paths(q0, q1))
    if scene != "empty" and arm_name != "rod_mechanism":  # the rod stays below the clutter
        assert 0 < collides.sum() < len(q0)


def test_candidate_pairs_hold_every_contact():
    for arm_name, scene in scene_cases():
        arm = make_arm(arm_name)
        model = build_model(arm_name, scene)
        pairs = {tuple(sorted(p)) for p in candidate_pairs(model).tolist()}
        data = mujoco.MjData(model)
        rng = np.random.default_rng(6)
        lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
        seen = 0
        for q in rng.uniform(lower, upper, size=(200, arm.dof)):
            data.qpos[: arm.dof] = q
            mujoco.mj_kinematics(model, data)
            mujoco.mj_collision(model, data)
            for contact in data.contact[: data.ncon]:
                assert tuple(sorted((contact.geom1, contact.geom2))) in pairs, arm_name
                seen += 1
        assert seen > 0 or scene == "empty" or arm_name == "rod_mechanism"


def test_collision_boxes_become_meshes_on_the_same_corners():
    arm = make_arm("anthropomorphic")
    spec, _ = arm_spec(arm, tool=True)
    boxes_model = spec.compile()
    mesh_model = compile_spec(spec)
    converted = [
        g for g in range(boxes_model.ngeom)
        if boxes_model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX and boxes_model.geom_contype[g]
    ]
    assert converted
    q = np.random.default_rng(7).uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1])
    corners = {}
    for model in (boxes_model, mesh_model):
        data = mujoco.MjData(model)
        data.qpos[: arm.dof] = q
        mujoco.mj_kinematics(model, data)
        for g in converted:
            g_here = model.geom(boxes_model.geom(g).name).id
            rotation = data.geom_xmat[g_here].reshape(3, 3)
            if model is boxes_model:
                local = np.array(list(itertools.product((-1, 1), repeat=3))) * model.geom_size[g]
            else:
                assert model.geom_type[g_here] == mujoco.mjtGeom.mjGEOM_MESH
                mesh = model.geom_dataid[g_here]
                start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
                local = model.mesh_vert[start : start + count]
            corners.setdefault(g, []).append(data.geom_xpos[g_here] + local @ rotation.T)
    for before, after in corners.values():
        # Mesh vertices are stored in single precision: equal to ~1e-8 m.
        assert len(after) == 8
        gaps = np.linalg.norm(before[:, None] - after[None], axis=-1)
        assert gaps.min(axis=1).max() < 1e-6 and gaps.min(axis=0).max() < 1e-6


def test_box_pair_inside_the_clearance_is_reported():
    # Poses from an Anthropomorphic-v0 path where MuJoCo's box-box collider reported
    # nothing although the gripper was 8.8 mm from an obstacle (δ = 10 mm).
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    add_part(add_static_body(spec, "obstacle"), "obstacle", "box",
             [0.08459633134906212, 0.08459633134906212, 0.05], (1, 1, 1, 1),
             pos=[0.46866854420298976, 1.0438620576081932, 0.05])
    body = spec.worldbody.add_body()
    body.name = "gripper"
    body.pos = [0.3792117614881976, 1.1926795257864307, 0.1245263783321062]
    body.quat = [0.5439240934929546, -0.18155781241441532, 0.08804163288812153,
                 -0.8145133590970458]
    joint = body.add_joint()
    joint.type = mujoco.mjtJoint.mjJNT_SLIDE
    add_part(body, "gripper", "box", [0.06, 0.03, 0.02], (1, 1, 1, 1))
    model = compile_spec(spec)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    distance = mujoco.mj_geomDistance(
        model, data, model.geom("obstacle").id, model.geom("gripper").id, 1.0, None
    )
    assert 0.008 < distance < 0.0095
    checker = CollisionChecker(model, dof=1)
    assert checker.collides(np.zeros(1))
    assert [c.distance for c in checker.contacts(np.zeros(1))] == pytest.approx([distance])


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_clearance_verdict_is_the_exact_distance(arm_name, scene):
    # A configuration collides exactly when some candidate pair is closer than δ by
    # mj_geomDistance (away from a thin band where the two computations may round apart).
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    checker = CollisionChecker(model, dof=arm.dof, backend="loop")
    pairs = candidate_pairs(model)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(8)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(150, arm.dof))
    verdicts = checker.collides(q)
    for row, verdict in zip(q, verdicts, strict=True):
        data.qpos[: arm.dof] = row
        mujoco.mj_kinematics(model, data)
        nearest = min(mujoco.mj_geomDistance(model, data, a, b, 1.0, None) for a, b in pairs)
        if abs(nearest - checker.resolution) > 1e-6:
            assert verdict == (nearest < checker.resolution), (row, nearest)


def test_advancing_loop_handles_a_tilted_plane():
    # The floor is level; a wall-like tilted plane checks the half-space bound's normal.
    arm = make_arm("anthropomorphic")
    spec, _ = arm_spec(arm)
    wall = spec.worldbody.add_geom()
    wall.name = "wall"
    wall.type = mujoco.mjtGeom.mjGEOM_PLANE
    wall.size = [0.0, 0.0, 0.05]
    wall.pos = [1.2, 0.0, 1.0]
    wall.quat = [np.cos(0.6), 0.0, -np.sin(0.6), 0.0]  # normal tilted 69° from vertical
    model = compile_spec(spec)
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    flat = CollisionChecker(model, dof=arm.dof, backend="batch", nthread=1)
    q0, q1 = _short_paths(arm, np.random.default_rng(9), 60)
    collides, first = loop.check_paths(q0, q1)
    np.testing.assert_equal((collides, first), flat.check_paths(q0, q1))
    touched = {
        name
        for i in np.flatnonzero(collides)
        for c in loop.contacts(q0[i] + first[i] * (q1[i] - q0[i]))
        for name in (c.geom1, c.geom2)
    }
    assert "wall" in touched


def test_free_path_results_compare_equal():
    # first_fraction is NaN on a free path; two free results must still be equal.
    from ikbranch_gym.envs.models.collision import PathResult

    free = [PathResult(False, float("nan"), (), 12) for _ in range(2)]
    assert free[0] == free[1] and hash(free[0]) == hash(free[1])
    assert free[0] != PathResult(False, float("nan"), (), 13)
    assert PathResult(True, 0.5, (), 12) != PathResult(True, 0.25, (), 12)
