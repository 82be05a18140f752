"""Pair bounds never exceed the distance."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from envs.kinematics import make_arm
from envs.models import CollisionChecker, build_model
from envs.models.builders import add_part, compile_spec
from envs.models.filter import kernels, layout, shapes
from envs.models.filter import tree as kinematics
from tests.envs.models.conftest import scene_cases


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_pair_bounds_never_exceed_mujocos_distance(arm_name, scene):
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    checker = CollisionChecker(model, dof=arm.dof, backend="compiled")
    scene_arrays = checker._filter.scene
    arrays, geometry = scene_arrays.tree, scene_arrays.geometry
    scene = kernels._scene(geometry, 0)
    slot_type, slot_size, slot_radius = scene[4], scene[5], scene[6]
    pair_a, pair_b = scene[7], scene[8]
    data = mujoco.MjData(model)
    xpos, xmat, wpos, wrot, _, _ = kernels._work(arrays, geometry)
    rng = np.random.default_rng(27)
    exact_ones = 0
    for q in rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(40, arm.dof)):
        qpos = model.qpos0.copy()
        qpos[: arm.dof] = q
        kinematics._forward(*arrays[:12], qpos, xpos, xmat)
        kinematics._place_slots(*scene[:4], xpos, xmat, wpos, wrot)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        for a, b in zip(pair_a, pair_b, strict=True):
            g1, g2 = scene_arrays.slot_geom[a], scene_arrays.slot_geom[b]
            distance = mujoco.mj_geomDistance(model, data, int(g1), int(g2), 10.0, None)
            frame_a = (kernels._centre(wpos, a), kernels._rotation(wrot, a))
            frame_b = (kernels._centre(wpos, b), kernels._rotation(wrot, b))
            bound = shapes._bound_pair(slot_type[a], *frame_a, kernels._size(slot_size, a),
                                       slot_type[b], *frame_b, kernels._size(slot_size, b))
            # A bound only has to be right about separation (it proves "farther than
            # the margin"); for a penetrating pair it only has to be ≤ 0.
            assert bound <= max(distance, 0.0) + 1e-9, (model.geom(int(g1)).name,
                                                        model.geom(int(g2)).name)
            sphere = shapes._bound_pair(layout.SPHERE, frame_a[0], frame_a[1],
                                        (slot_radius[a], 0.0, 0.0), slot_type[b], *frame_b,
                                        kernels._size(slot_size, b))
            assert sphere <= max(distance, 0.0) + 1e-9
            exact_ones += slot_type[a] == slot_type[b] == layout.CAPSULE
            if slot_type[a] == slot_type[b] == layout.CAPSULE and distance > 1e-3:
                assert bound == pytest.approx(distance, abs=1e-6)  # capsule pairs: exact


def test_segment_box_distance_is_exact():
    rng = np.random.default_rng(28)
    for _ in range(300):
        centre = rng.normal(size=3)
        rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        half = rng.uniform(0.05, 1.0, size=3)
        a, b = rng.normal(scale=2.0, size=(2, 3))
        t = np.linspace(0, 1, 4001)[:, None]
        points = (a + t * (b - a) - centre) @ rotation
        excess = np.maximum(np.abs(points) - half, 0.0)
        dense = np.linalg.norm(excess, axis=1).min()
        value = shapes._segment_box(*a, *b, tuple(centre), tuple(rotation.ravel()), *half)
        assert value <= dense + 1e-12
        assert value == pytest.approx(dense, abs=2e-3 * np.linalg.norm(b - a))


def test_box_box_bound_never_exceeds_the_distance():
    rng = np.random.default_rng(29)
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    for name in ("one", "two"):
        body = spec.worldbody.add_body()
        body.name = name
        body.add_joint().type = mujoco.mjtJoint.mjJNT_SLIDE  # moving: frames recomputed
        add_part(body, name, "box", [0.1, 0.2, 0.3], (1, 1, 1, 1))
    model = compile_spec(spec)  # meshes: MuJoCo's general convex distance
    data = mujoco.MjData(model)
    geoms = [model.geom(name).id for name in ("one", "two")]
    close = 0
    for _ in range(400):
        for name in ("one", "two"):
            rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
            rotation *= np.sign(np.linalg.det(rotation))
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, rotation.ravel())
            model.body(name).pos, model.body(name).quat = rng.normal(scale=0.4, size=3), quat
        mujoco.mj_kinematics(model, data)
        frames = [(tuple(data.geom_xpos[g]), tuple(data.geom_xmat[g]), *model.geom_aabb[g][3:])
                  for g in geoms]
        distance = mujoco.mj_geomDistance(model, data, *geoms, 10.0, None)
        (c1, r1, *h1), (c2, r2, *h2) = frames
        bound = shapes._box_box(c1, r1, *h1, c2, r2, *h2)
        assert bound <= max(distance, 0.0) + 1e-7
        close += 0 < distance < 0.2
    assert close > 20


