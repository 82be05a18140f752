"""What the filter reads off a model: containers that hold their geoms, rates that bound
how fast pairs close, refused models, MuJoCo's quaternion matrices."""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import CollisionChecker, build_model
from ikbranch_gym.envs.models.collision import candidate_pairs
from ikbranch_gym.envs.models.filter import kernels, layout
from ikbranch_gym.envs.models.filter import tree as kinematics
from tests.envs.models.conftest import scene_cases


def _surface_points(model: mujoco.MjModel, geom: int, rng) -> np.ndarray:
    """Points of the geom's solid in its own frame, on or near its surface (meshes: the
    vertices, whose hull MuJoCo collides)."""
    kind, size = model.geom_type[geom], model.geom_size[geom]
    directions = rng.normal(size=(200, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    types = mujoco.mjtGeom
    if kind == types.mjGEOM_SPHERE:
        return size[0] * directions
    if kind == types.mjGEOM_CAPSULE:
        ends = np.where(rng.random(200)[:, None] < 0.5, 1.0, -1.0) * [0, 0, size[1]]
        return ends + size[0] * directions
    if kind == types.mjGEOM_BOX:
        return np.array(list(itertools.product((-1, 1), repeat=3))) * size
    if kind == types.mjGEOM_CYLINDER:
        angle = rng.uniform(0, 2 * np.pi, 200)
        height = rng.choice([-1.0, 1.0], 200) * size[1]
        return np.stack([size[0] * np.cos(angle), size[0] * np.sin(angle), height], axis=1)
    if kind == types.mjGEOM_ELLIPSOID:
        return directions * size
    if kind == types.mjGEOM_MESH:
        mesh = model.geom_dataid[geom]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        return model.mesh_vert[start : start + count].astype(np.float64)
    raise AssertionError(f"no test points for geom type {kind}")


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_containers_hold_their_geoms(arm_name, scene):
    model = build_model(arm_name, scene)
    pairs = candidate_pairs(model)
    rng = np.random.default_rng(26)
    for geom in np.unique(pairs):
        kind, size, offset, radius = layout.container(model, int(geom))
        if kind in (layout.PLANE, layout.UNBOUNDED):
            continue
        p = (_surface_points(model, int(geom), rng) - offset) * (1 - 1e-12)  # container frame
        radial = np.hypot(p[:, 0], p[:, 1])
        inside = {
            layout.SPHERE: np.linalg.norm(p, axis=1) <= size[0],
            layout.CAPSULE: np.hypot(radial, np.maximum(np.abs(p[:, 2]) - size[1], 0)) <= size[0],
            layout.BOX: np.all(np.abs(p) <= size, axis=1),
            layout.CYLINDER: (radial <= size[0]) & (np.abs(p[:, 2]) <= size[1]),
        }[kind]
        assert inside.all(), model.geom(int(geom)).name
        assert (np.linalg.norm(p, axis=1) <= radius).all()



@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_pair_rates_bound_how_fast_pairs_close(arm_name, scene):
    # Along random paths, the distance between any point of a's bounding sphere and any
    # of b's (fixed in their geoms' frames) changes no faster than the pair's lever-arm
    # rate: joints that move both geoms keep such distances, the others are bounded. A
    # joint that turns one geom about an axis of symmetry of either keeps the distance of
    # the two geoms (not of every pair of their points): where such a joint dropped out,
    # MuJoCo's distance of the two geoms changes no faster than the rate.
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    checker = CollisionChecker(model, dof=arm.dof, backend="compiled")
    compiled = checker._filter.scene
    arrays, geometry = compiled.tree, compiled.geometry
    scene = kernels._scene(geometry, 0)
    slot_radius, pair_a, pair_b, pair_lever = scene[6], scene[7], scene[8], scene[10].T
    xpos, xmat, wpos, wrot, _, _ = kernels._work(arrays, geometry)
    directions = np.concatenate([np.zeros((1, 3)), np.eye(3), -np.eye(3)])
    finite = np.where(np.isfinite(slot_radius), slot_radius, 0.0)
    local = finite[:, None, None] * directions[None]  # (slots, 7, 3)
    # The levers before any symmetry: a's alone against a static b, else the joints that
    # move one geom and not the other.
    lever, moved, static = compiled.slot_lever, compiled.slot_moved, compiled.slot_static
    rigid = np.array([lever[a] if static[b] else
                      np.where(moved[a] & ~moved[b], lever[a], 0.0)
                      + np.where(moved[b] & ~moved[a], lever[b], 0.0)
                      for a, b in zip(pair_a, pair_b, strict=True)])
    symmetric = (pair_lever != rigid).any(axis=1)
    assert np.array_equal(pair_lever <= rigid, np.ones_like(rigid, dtype=bool))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(30)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    t = np.linspace(0, 1, 201)
    for _ in range(6):
        q0, q1 = rng.uniform(lower, upper, size=(2, arm.dof))
        rates = pair_lever[:, : arm.dof] @ np.abs(q1 - q0)
        points, distances = [], []
        for ti in t:
            qpos = model.qpos0.copy()
            qpos[: arm.dof] = q0 + ti * (q1 - q0)
            kinematics._forward(*arrays[:12], qpos, xpos, xmat)
            kinematics._place_slots(*scene[:4], xpos, xmat, wpos, wrot)
            points.append(wpos[:, None] + np.einsum("sij,skj->ski", wrot, local))
            data.qpos[:] = qpos
            mujoco.mj_kinematics(model, data)
            distances.append([
                max(mujoco.mj_geomDistance(model, data, int(compiled.slot_geom[a]),
                                           int(compiled.slot_geom[b]), 100.0, None), 0.0)
                for a, b in zip(pair_a[symmetric], pair_b[symmetric], strict=True)])
        points = np.array(points)  # (T, slots, 7, 3)
        for k, (a, b) in enumerate(zip(pair_a, pair_b, strict=True)):
            if symmetric[k]:
                continue
            gaps = np.linalg.norm(points[:, a, :, None] - points[:, b, None, :], axis=-1)
            change = np.abs(np.diff(gaps, axis=0)).max()
            assert change <= rates[k] * (t[1] - t[0]) + 1e-12, (k, change, rates[k])
        if symmetric.any():
            change = np.abs(np.diff(np.array(distances), axis=0)).max(axis=0)
            # MuJoCo's convex solver's tolerance (1e-6) on either side.
            assert (change <= rates[symmetric] * (t[1] - t[0]) + 2e-6).all()



@pytest.mark.parametrize("arm_name", ["ur5e", "spherical", "cylindrical"])
def test_a_static_partner_symmetric_about_a_world_fixed_axis_drops_its_joint(arm_name):
    # A joint whose axis line stays put in the world (the base's pan; the cylindrical
    # arm's column turn above its vertical slide) turns the moving geom about that line:
    # a static partner symmetric about it (the floor, a base plate, a clutter cylinder on
    # the axis) keeps MuJoCo's distance to it whatever the joint does, so the joint drops
    # out of the pair's lever, per scene: a partner laid off the axis takes it back.
    import gymnasium as gym

    env = gym.make("IKBranch/Anthropomorphic-v3", arm=arm_name, n_waypoints=3).unwrapped
    checker, arm = env.checker, env.arm
    scene, model = checker._filter.scene, checker.model
    data = mujoco.MjData(model)
    rng = np.random.default_rng(5)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    for seed in (0, 3):
        env._lay_scene(seed)
        own, now = scene.pair_lever_own, scene.pair_lever[0]
        near = scene.pair_kind[0] != layout.OUT_OF_REACH
        dropped = np.argwhere((own != now) & near[None])
        assert len(dropped) and (now <= own).all()
        assert scene.slot_static[scene.pair_b[dropped[:, 1]]].all()
        for j, k in dropped.tolist():
            g1, g2 = (int(scene.slot_geom[s]) for s in (scene.pair_a[k], scene.pair_b[k]))
            q = rng.uniform(lower, upper)
            distances = []
            for value in np.linspace(lower[j], upper[j], 41):
                q[j] = value
                data.qpos[: arm.dof] = q
                mujoco.mj_kinematics(model, data)
                distances.append(mujoco.mj_geomDistance(model, data, g1, g2, 100.0, None))
            # MuJoCo's convex solver's tolerance (1e-6) on either side.
            assert np.ptp(distances) <= 2e-6, (model.geom(g1).name, model.geom(g2).name, j)
    # A clutter cylinder moved onto the pan axis drops the pan from its pairs; moved off,
    # the pairs take it back (the refresh rereads the levers as it rereads the places).
    pan = int(np.flatnonzero(~np.isnan(scene.jnt_line[:, 0]))[0])
    point, direction = scene.jnt_line[pan, :3], scene.jnt_line[pan, 3:]
    cylinder = next(int(g) for g in scene.slot_geom[scene.slot_static]
                    if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER
                    and model.geom(int(g)).name.startswith("clutter"))
    pairs = np.flatnonzero(scene.slot_geom[scene.pair_b] == cylinder)
    pairs = pairs[scene.pair_lever_own[pan, pairs] > 0]
    assert len(pairs)
    model.geom_quat[cylinder] = [1.0, 0.0, 0.0, 0.0]
    assert np.allclose(np.abs(direction), [0.0, 0.0, 1.0])
    for shift, expected in ((0.0, 0.0), (0.3, None)):
        model.geom_pos[cylinder] = point + 0.5 * direction + [shift, 0.0, 0.0]
        checker.refresh_static(np.array([cylinder]))
        levers = scene.pair_lever[0][pan, pairs]
        want = scene.pair_lever_own[pan, pairs] if expected is None else expected
        np.testing.assert_array_equal(levers, want)


def test_unsupported_models_are_refused():
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body()
    body.add_joint().type = mujoco.mjtJoint.mjJNT_BALL
    geom = body.add_geom()
    geom.size = [0.1, 0, 0]
    model = spec.compile()
    with pytest.raises(ValueError, match="hinge and slide"):
        layout.compile_scene(model, model.nq, np.zeros((0, 2), dtype=np.int64))



def test_witnesses_only_where_mujocos_convex_collider_runs_its_default_course():
    # The witnesses were studied with MuJoCo's default CCD iterations and tolerance; with
    # fewer iterations its convex collider misses contacts they prove, so such a model
    # gets none (MuJoCo decides every contact), and a stricter one keeps them.
    arm = make_arm("ur5e")
    model = build_model("ur5e", "random_clutter")
    pairs = candidate_pairs(model)

    def witnessed(iterations: int, tolerance: float) -> int:
        model.opt.ccd_iterations, model.opt.ccd_tolerance = iterations, tolerance
        scene = layout.compile_scene(model, arm.dof, pairs)
        return int(np.isfinite(scene.pair_contact).sum())

    default = witnessed(layout.CCD_ITERATIONS, layout.CCD_TOLERANCE)
    assert default > 50
    assert witnessed(100, 1e-8) == default
    assert witnessed(layout.CCD_ITERATIONS - 1, layout.CCD_TOLERANCE) == 0
    assert witnessed(layout.CCD_ITERATIONS, 10 * layout.CCD_TOLERANCE) == 0


def test_quaternion_matrices_are_mujocos():
    rng = np.random.default_rng(8)
    quats = rng.normal(size=(2000, 4))
    quats /= np.linalg.norm(quats, axis=1)[:, None]
    quats[0] = (1.0, 0.0, 0.0, 0.0)
    for quat in quats:
        expected = np.zeros(9)
        mujoco.mju_quat2Mat(expected, quat)
        np.testing.assert_allclose(layout._quat_to_mat(quat), expected.reshape(3, 3), rtol=0,
                                   atol=1e-15)
    np.testing.assert_array_equal(layout._quat_to_mat(quats[0]), np.eye(3))
