"""Collision checks: configurations, paths, the resolution guarantee, batch vs loop."""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
import pytest

from envs.kinematics import ARM_NAMES, make_arm
from envs.models import CollisionChecker, arm_spec, build_model
from envs.models.builders import add_part, add_static_body
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


def _bounding_sphere_points(model, data):
    """(ngeom, 7, 3): every geom's centre and the six points of its bounding sphere on its
    local axes, in world coordinates (the lever-arm bound covers the whole sphere)."""
    offsets = np.concatenate([np.zeros((1, 3)), np.eye(3), -np.eye(3)])
    local = model.geom_rbound[:, None, None] * offsets[None]
    rotation = data.geom_xmat.reshape(-1, 3, 3)
    return data.geom_xpos[:, None] + np.einsum("gij,gkj->gki", rotation, local)


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
        positions = []
        for q in samples:
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            positions.append(_bounding_sphere_points(model, data))
        moved = np.linalg.norm(np.diff(np.array(positions), axis=0), axis=-1).max()
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
