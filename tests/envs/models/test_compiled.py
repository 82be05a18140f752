"""The compiled filter: its geometry is conservative, and its answers are MuJoCo's.

The exactness tests compare the ``"compiled"`` backend with ``"loop"`` (the advancing
Python loop, itself tested equal to checking every grid sample in test_collision.py) and
demand equality: the same verdict and the same first colliding sample for every path, the
same contact count for every configuration.
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np
import pytest

from envs.kinematics import make_arm
from envs.models import CollisionChecker, arm_spec, build_model, native
from envs.models import compiled as C
from envs.models.builders import add_part, add_static_body, compile_spec
from envs.models.collision import candidate_pairs
from tests.envs.models.conftest import scene_cases

#: Paths per arm × scene in the exactness tests (half short moves, half across the range).
PATHS = 2000


def _checker(arm_name: str, scene: str, backend: str, **kwargs) -> CollisionChecker:
    arm = make_arm(arm_name)
    return CollisionChecker(build_model(arm_name, scene, **kwargs), dof=arm.dof, backend=backend)


def _paths(arm, rng, count):
    """Half: from uniform configurations by up to a quarter of every joint range; half:
    between two uniform configurations."""
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    q0 = rng.uniform(lower, upper, size=(count, arm.dof))
    near = np.clip(q0 + rng.uniform(-0.25, 0.25, size=q0.shape) * (upper - lower), lower, upper)
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


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_configuration_contact_counts_equal_the_loop(arm_name, scene):
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    compiled = CollisionChecker(model, dof=arm.dof, backend="compiled")
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    rng = np.random.default_rng(21)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(PATHS, arm.dof))
    counts = loop.n_contacts(q)
    np.testing.assert_array_equal(compiled.n_contacts(q), counts)
    assert compiled.n_contacts(q.reshape(2, -1, arm.dof)).shape == (2, PATHS // 2)


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
        before = checker._filter.counters[0]
        checker.first_free_rows(q, 1)
        assert checker._filter.counters[0] - before == free[0] + 1


def test_milling_cell_transfers_equal_the_loop():
    arm = make_arm("anthropomorphic")
    model = build_model("anthropomorphic", "milling_cell")
    from envs.models import milling_cell_poses

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
    bounded, exact, _, _ = checker._filter.counters
    assert exact < 0.01 * grid and bounded < 0.1 * grid



def test_mujoco_checks_that_find_no_contact_are_counted():
    # An ellipsoid is bounded by its box, whose corners stick out: samples there go to
    # MuJoCo and come back free (false alarms, counters[3]). Every colliding sample reaches
    # MuJoCo (the bounds never prove it free), so the checks that found a contact are the
    # colliding configurations, and one per colliding path in a verdict-only call.
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
    _, checks, _, alarms = counters - before
    assert colliding.any() and alarms > 0 and checks - alarms == colliding.sum()
    q0, q1 = _paths(arm, np.random.default_rng(26), 400)
    before = counters.copy()
    hits = checker.paths_collide(q0, q1)
    _, checks, _, alarms = counters - before
    assert hits.any() and alarms > 0 and checks - alarms == hits.sum()


# ------------------------------------------------------------------ the geometry itself
@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_forward_kinematics_equals_mujoco(arm_name, scene):
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene, tool=True) if scene != "milling_cell" else build_model(
        arm_name, scene)
    checker = CollisionChecker(model, dof=arm.dof, backend="compiled")
    scene_arrays = checker._filter.scene
    tree = scene_arrays.tree
    data = mujoco.MjData(model)
    xpos, xmat = tree[-2].copy(), tree[-1].copy()
    rng = np.random.default_rng(25)
    for q in rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(100, arm.dof)):
        qpos = model.qpos0.copy()
        qpos[: arm.dof] = q
        C._forward(*tree[:12], qpos, xpos, xmat)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(xpos, data.xpos, atol=1e-12)
        np.testing.assert_allclose(xmat.reshape(-1, 9), data.xmat, atol=1e-12)


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
        kind, size, offset, radius = C.container(model, int(geom))
        if kind in (C.PLANE, C.UNBOUNDED):
            continue
        p = (_surface_points(model, int(geom), rng) - offset) * (1 - 1e-12)  # container frame
        radial = np.hypot(p[:, 0], p[:, 1])
        inside = {
            C.SPHERE: np.linalg.norm(p, axis=1) <= size[0],
            C.CAPSULE: np.hypot(radial, np.maximum(np.abs(p[:, 2]) - size[1], 0)) <= size[0],
            C.BOX: np.all(np.abs(p) <= size, axis=1),
            C.CYLINDER: (radial <= size[0]) & (np.abs(p[:, 2]) <= size[1]),
        }[kind]
        assert inside.all(), model.geom(int(geom)).name
        assert (np.linalg.norm(p, axis=1) <= radius).all()


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_pair_bounds_never_exceed_mujocos_distance(arm_name, scene):
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    checker = CollisionChecker(model, dof=arm.dof, backend="compiled")
    scene_arrays = checker._filter.scene
    tree, geometry = scene_arrays.tree, scene_arrays.geometry
    slot_type, slot_size, slot_radius = geometry[4], geometry[5], geometry[6]
    pair_a, pair_b = geometry[7], geometry[8]
    data = mujoco.MjData(model)
    xpos, xmat, wpos, wrot, _, _ = C._work(tree, geometry)
    rng = np.random.default_rng(27)
    exact_ones = 0
    for q in rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(40, arm.dof)):
        qpos = model.qpos0.copy()
        qpos[: arm.dof] = q
        C._forward(*tree[:12], qpos, xpos, xmat)
        C._place_slots(*geometry[:4], xpos, xmat, wpos, wrot)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        for a, b in zip(pair_a, pair_b, strict=True):
            g1, g2 = scene_arrays.slot_geom[a], scene_arrays.slot_geom[b]
            distance = mujoco.mj_geomDistance(model, data, int(g1), int(g2), 10.0, None)
            frame_a = (C._centre(wpos, a), C._rotation(wrot, a))
            frame_b = (C._centre(wpos, b), C._rotation(wrot, b))
            bound = C._bound_pair(slot_type[a], *frame_a, C._size(slot_size, a),
                                  slot_type[b], *frame_b, C._size(slot_size, b))
            # A bound only has to be right about separation (it proves "farther than
            # the margin"); for a penetrating pair it only has to be ≤ 0.
            assert bound <= max(distance, 0.0) + 1e-9, (model.geom(int(g1)).name,
                                                        model.geom(int(g2)).name)
            sphere = C._bound_pair(C.SPHERE, frame_a[0], frame_a[1], (slot_radius[a], 0.0, 0.0),
                                   slot_type[b], *frame_b, C._size(slot_size, b))
            assert sphere <= max(distance, 0.0) + 1e-9
            exact_ones += slot_type[a] == slot_type[b] == C.CAPSULE
            if slot_type[a] == slot_type[b] == C.CAPSULE and distance > 1e-3:
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
        value = C._segment_box(*a, *b, tuple(centre), tuple(rotation.ravel()), *half)
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
        bound = C._box_box(c1, r1, *h1, c2, r2, *h2)
        assert bound <= max(distance, 0.0) + 1e-7
        close += 0 < distance < 0.2
    assert close > 20


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_pair_rates_bound_how_fast_pairs_close(arm_name, scene):
    # Along random paths, the distance between any point of a's bounding sphere and any
    # of b's (fixed in their geoms' frames) changes no faster than the pair's lever-arm
    # rate: joints that move both geoms keep such distances, the others are bounded.
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    checker = CollisionChecker(model, dof=arm.dof, backend="compiled")
    tree, geometry = checker._filter.scene.tree, checker._filter.scene.geometry
    slot_radius, pair_a, pair_b, pair_lever = geometry[6], geometry[7], geometry[8], geometry[10]
    xpos, xmat, wpos, wrot, _, _ = C._work(tree, geometry)
    directions = np.concatenate([np.zeros((1, 3)), np.eye(3), -np.eye(3)])
    finite = np.where(np.isfinite(slot_radius), slot_radius, 0.0)
    local = finite[:, None, None] * directions[None]  # (slots, 7, 3)
    rng = np.random.default_rng(30)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    t = np.linspace(0, 1, 201)
    for _ in range(6):
        q0, q1 = rng.uniform(lower, upper, size=(2, arm.dof))
        rates = pair_lever[:, : arm.dof] @ np.abs(q1 - q0)
        points = []
        for ti in t:
            qpos = model.qpos0.copy()
            qpos[: arm.dof] = q0 + ti * (q1 - q0)
            C._forward(*tree[:12], qpos, xpos, xmat)
            C._place_slots(*geometry[:4], xpos, xmat, wpos, wrot)
            points.append(wpos[:, None] + np.einsum("sij,skj->ski", wrot, local))
        points = np.array(points)  # (T, slots, 7, 3)
        for k, (a, b) in enumerate(zip(pair_a, pair_b, strict=True)):
            gaps = np.linalg.norm(points[:, a, :, None] - points[:, b, None, :], axis=-1)
            change = np.abs(np.diff(gaps, axis=0)).max()
            assert change <= rates[k] * (t[1] - t[0]) + 1e-12, (k, change, rates[k])


# ---------------------------------------------------------------------- MuJoCo bridge
def test_ncon_view_follows_mujoco():
    model = build_model("anthropomorphic", "milling_cell")
    data = mujoco.MjData(model)
    view = native.ncon_view(data)
    rng = np.random.default_rng(31)
    seen = set()
    for q in rng.uniform(-2, 2, size=(50, 6)):
        data.qpos[:6] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        assert view[0] == data.ncon
        seen.add(data.ncon)
    assert len(seen) > 3


def test_unsupported_models_are_refused():
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body()
    body.add_joint().type = mujoco.mjtJoint.mjJNT_BALL
    geom = body.add_geom()
    geom.size = [0.1, 0, 0]
    model = spec.compile()
    with pytest.raises(ValueError, match="hinge and slide"):
        C.compile_scene(model, model.nq, np.zeros((0, 2), dtype=np.int64))


def test_quaternion_matrices_are_mujocos():
    rng = np.random.default_rng(8)
    quats = rng.normal(size=(2000, 4))
    quats /= np.linalg.norm(quats, axis=1)[:, None]
    quats[0] = (1.0, 0.0, 0.0, 0.0)
    for quat in quats:
        expected = np.zeros(9)
        mujoco.mju_quat2Mat(expected, quat)
        np.testing.assert_allclose(C._quat_to_mat(quat), expected.reshape(3, 3), rtol=0,
                                   atol=1e-15)
    np.testing.assert_array_equal(C._quat_to_mat(quats[0]), np.eye(3))
