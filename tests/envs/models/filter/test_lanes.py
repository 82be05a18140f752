"""The lanes prove only what holds: their covers hold the geoms, their frames are MuJoCo's,
a step they prove is free at every grid sample within it, and the path checks that use them
answer exactly as without them."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import CollisionChecker, build_model
from ikbranch_gym.envs.models.builders import compile_spec
from ikbranch_gym.envs.models.filter import COUNTERS
from ikbranch_gym.envs.models.filter.kernels import (
    BY_WITNESS,
    LANE_FUNCTION,
    bound_configurations,
)
from ikbranch_gym.envs.models.filter.lanes import (
    BOX_COVERS,
    LANES,
    box_cells,
    library,
    primitive_box_pairs,
    usable,
)
from ikbranch_gym.envs.models.filter.layout import BOX, CYLINDER, SPHERE

#: Arms in their clutter: capsules and cylinders; with boxes (housings, prismatic links,
#: grippers) among them.
BOX_ARMS = ("anthropomorphic", "cartesian", "spherical")
ARMS = ["ur5e", "kuka_kr6_r700", "abb_irb2600", "opw", *BOX_ARMS]


def _checker(arm_name: str, backend: str = "compiled") -> CollisionChecker:
    return CollisionChecker(build_model(arm_name, "random_clutter", seed=3),
                            dof=make_arm(arm_name).dof, backend=backend)


def _surface(kind: int, size: np.ndarray, rng: np.random.Generator, count: int) -> np.ndarray:
    """Points on the surface of a container (its frame): the farthest from its axis; a
    box's faces, edges and corners."""
    r, h = size[0], size[1]
    angle = rng.uniform(0.0, 2.0 * np.pi, count)
    if kind == BOX:
        face = rng.uniform(-1.0, 1.0, (count, 3))
        face[np.arange(count), rng.integers(0, 3, count)] = rng.choice([-1.0, 1.0], count)
        edge = rng.choice([-1.0, 1.0], (count, 3))
        edge[np.arange(count), rng.integers(0, 3, count)] = rng.uniform(-1.0, 1.0, count)
        corner = rng.choice([-1.0, 1.0], (count, 3))
        return np.vstack([face, edge, corner]) * size
    if kind == SPHERE:
        v = rng.normal(size=(count, 3))
        return r * v / np.linalg.norm(v, axis=1, keepdims=True)
    z = rng.uniform(-h, h, count)
    side = np.column_stack([r * np.cos(angle), r * np.sin(angle), z])
    if kind == CYLINDER:  # the side, and the two faces out to their rims
        rho = r * np.sqrt(rng.uniform(0.0, 1.0, count))
        face = np.column_stack([rho * np.cos(angle), rho * np.sin(angle),
                                h * rng.choice([-1.0, 1.0], count)])
        return np.vstack([side, face])
    v = rng.normal(size=(count, 3))  # CAPSULE: the side, and the caps
    cap = r * v / np.linalg.norm(v, axis=1, keepdims=True)
    cap[:, 2] = np.abs(cap[:, 2]) * rng.choice([-1.0, 1.0], count)
    cap[:, 2] += np.sign(cap[:, 2]) * h
    return np.vstack([side, cap])


def _within_step(q0, q1, n, mid, steps, lane):
    """The grid samples of lane ``lane``'s path (``q0`` → ``q1`` in ``n`` steps) within its
    proven step of its sample ``mid``."""
    reach = int(steps[lane] * n[lane])
    grid = np.arange(max(mid[lane] - reach, 0), min(mid[lane] + reach, n[lane]) + 1)
    return q0[lane] + (grid / n[lane])[:, None] * (q1[lane] - q0[lane])


@pytest.mark.parametrize("arm_name", ARMS)
def test_the_covers_hold_every_moving_container(arm_name):
    scene = _checker(arm_name)._filter.scene
    start, centres, radii = _checker(arm_name)._filter.lanes.covers
    rng = np.random.default_rng(1)
    held = boxes = 0
    for s in np.flatnonzero(~scene.slot_static):
        kind, size = int(scene.slot_type[s]), scene.slot_size[0, s]
        if start[s] == start[s + 1]:
            continue
        points = _surface(kind, size, rng, 5000)
        body = scene.slot_pos[0, s] + points @ scene.slot_rot[0, s].T
        mine = slice(start[s], start[s + 1])
        gaps = np.linalg.norm(body[:, None] - centres[None, mine], axis=2) - radii[None, mine]
        assert np.all(gaps.min(axis=1) <= 0.0), f"slot {s}: a point outside every cover"
        # ... and not by much: a capsule's cover sphere's radius is at most √1.25 times
        # the geom's (a box's: test_a_box_is_held_by_the_spheres_of_its_cells).
        if kind != BOX:
            assert radii[mine].max() <= 1.12 * size[0] + 1e-9
        boxes += kind == BOX
        # Within the slot's bounding radius, as the kernel's rounding allowance assumes.
        bounding = scene.slot_radius[0, s] * (1.0 + 1e-12) + 1e-12
        assert np.all(np.linalg.norm(centres[mine] - scene.slot_pos[0, s], axis=1) <= bounding)
        assert np.all(radii[mine] <= bounding)
        held += 1
    assert held >= 6
    assert (boxes > 0) == (arm_name in BOX_ARMS)


@pytest.mark.parametrize(("half", "cuts"), [((0.1, 0.1, 0.1), (2, 2, 2)),
                                             ((0.01, 0.1, 0.1), (1, 4, 4)),
                                             ((0.05, 0.05, 0.4), (1, 1, 8))])
def test_a_box_is_held_by_the_spheres_of_its_cells(half, cuts):
    # Derived by hand, of all cuts into at most 16 cells the spheres reaching least past
    # the faces (radius less the cell's least half): the cube's eight cells reach 0.0366
    # (one cell 0.0732, 2×2×3 0.0449); the plate's 4×4 0.0267 (1×3×5 0.0301, 1×2×8 0.0425);
    # the link's eight along its length 0.0366 (seven 0.0407, nine 0.0395, 1×2×8 0.0500).
    cells = box_cells(np.array(half))
    assert len(cells) == np.prod(cuts) <= BOX_COVERS
    cell = np.array(half) / np.array(cuts)
    centres = np.array([c for c, _ in cells])
    for axis in range(3):
        expected = -half[axis] + cell[axis] * (2 * np.arange(cuts[axis]) + 1)
        np.testing.assert_allclose(np.unique(centres[:, axis]), expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose([r for _, r in cells], np.linalg.norm(cell), rtol=1e-15)


@pytest.mark.parametrize("arm_name", ARMS)
def test_the_lanes_frames_are_mujocos(arm_name):
    checker = _checker(arm_name)
    lanes, model = checker._filter.lanes, checker.model
    data = mujoco.MjData(model)
    rng = np.random.default_rng(2)
    nq, dof = model.nq, checker.dof
    start = np.tile(model.qpos0, (LANES, 1))
    start[:, :dof] = rng.uniform(-3.0 * np.pi, 3.0 * np.pi, (LANES, dof))  # every quadrant
    change = np.zeros((LANES, nq))
    change[:, :dof] = rng.uniform(-2.0, 2.0, (LANES, dof))
    t = rng.uniform(0.0, 1.0, LANES)
    npair = len(checker._filter.scene.pair_a)
    _, xpos, xmat = lanes.bound(start, change, t, np.zeros(LANES), np.zeros((LANES, npair)))
    moving = (checker._filter.scene.body_flags & 1) == 0
    assert moving.sum() >= dof
    for lane in range(LANES):
        data.qpos[:] = start[lane] + t[lane] * change[lane]
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(xpos[moving, :, lane], data.xpos[moving], rtol=0, atol=1e-12)
        np.testing.assert_allclose(xmat[moving, ..., lane],
                                   data.xmat.reshape(-1, 3, 3)[moving], rtol=0, atol=1e-12)


@pytest.mark.parametrize("arm_name", ARMS)
def test_a_step_the_lanes_prove_is_free_at_every_grid_sample_within_it(arm_name):
    checker, loop = _checker(arm_name), _checker(arm_name, backend="loop")
    lanes, scene = checker._filter.lanes, checker._filter.scene
    arm = make_arm(arm_name)
    rng = np.random.default_rng(4)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    nq, dof = checker.model.nq, checker.dof
    proved = unproved = 0
    for _ in range(12):
        q0 = rng.uniform(lower, upper, (LANES, dof))
        q1 = np.clip(q0 + rng.uniform(-0.3, 0.3, q0.shape) * (upper - lower), lower, upper)
        n = checker.n_steps(q0, q1)
        mid = rng.integers(0, n + 1)
        start, change = np.tile(checker.model.qpos0, (LANES, 1)), np.zeros((LANES, nq))
        start[:, :dof], change[:, :dof] = q0, q1 - q0
        rates = np.abs(q1 - q0) @ scene.pair_lever[0][:dof]
        cap = rng.uniform(0.0, 0.3, LANES)
        steps, _, _ = lanes.bound(start, change, mid / n, cap, rates)
        assert np.all(steps <= cap)
        for lane in range(LANES):
            if steps[lane] < 0.0:
                unproved += 1
                continue
            proved += 1
            assert not loop.collides(_within_step(q0, q1, n, mid, steps, lane)).any()
    assert proved > 0.2 * 12 * LANES and unproved > 0


@pytest.mark.parametrize("arm_name", ARMS)
def test_path_checks_answer_the_same_with_the_lanes_as_without(arm_name):
    checker = _checker(arm_name)
    arm = make_arm(arm_name)
    rng = np.random.default_rng(5)
    q0 = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (400, arm.dof))
    q1 = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (400, arm.dof))
    lanes = COUNTERS.index("lane samples")
    exact, counters = checker._filter._exact, checker._filter.counters
    function = int(exact[0, LANE_FUNCTION])
    assert function != 0
    answers = []
    for on in (function, 0):
        exact[0, LANE_FUNCTION] = on
        before = counters[lanes]
        answers.append((checker.paths_collide(q0, q1), *checker.check_paths(q0, q1)))
        assert (counters[lanes] > before) == bool(on)
    for with_lanes, without in zip(*answers, strict=True):
        np.testing.assert_array_equal(with_lanes, without)
    exact[0, LANE_FUNCTION] = function
    for m in range(20):  # one path alone fills the lanes with its intervals: the same answers
        before = counters[lanes]
        alone = checker.check_path(q0[m], q1[m])
        assert counters[lanes] > before
        assert alone.collides == answers[1][1][m]
        np.testing.assert_array_equal(alone.first_fraction, answers[1][2][m])


def test_a_stack_checks_each_scenes_paths_lane_for_lane_as_its_own_filter():
    # A vector env's survey asks a stack for a few paths in each sub-env's scene. The
    # stack takes a scene's paths as a call of that scene's own filter would: the same
    # first intervals per path (16 for a lone one), so the same lane calls, samples and
    # MuJoCo checks, and the same answers.
    from ikbranch_gym.envs.models.filter import FilterStack, path_steps
    from ikbranch_gym.envs.models.scenes import CLUTTER_SLOTS, ClutterSlots, draw_clutter

    arm = make_arm("ur5e")
    checkers = []
    for seed in (3, 4, 5, 6):
        checker = CollisionChecker(build_model("ur5e", "random_clutter", seed=None),
                                   dof=arm.dof)
        slots = ClutterSlots(checker.model, CLUTTER_SLOTS)
        slots.lay(draw_clutter(arm, seed, slots.base, CLUTTER_SLOTS), checker.model)
        checker.refresh_static(slots.geoms)
        checkers.append(checker)
    stack = FilterStack([checker._filter for checker in checkers])
    rng = np.random.default_rng(8)
    scenes = np.array([0, 1, 1, 2, 3, 3, 3])  # runs of one, two and three paths
    q0 = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (len(scenes), arm.dof))
    q1 = q0 + rng.uniform(-0.3, 0.3, q0.shape)
    steps = np.empty(len(scenes), dtype=np.int64)
    path_steps(q0, q1, checkers[0].lever, checkers[0].resolution, steps)
    for first in (True, False):
        before = stack.counters.copy()
        together = stack.paths(scenes, q0, q1, steps, first)
        spent = stack.counters - before
        alone, spent_alone = np.empty_like(together), np.zeros_like(spent)
        for i, checker in enumerate(checkers):
            mine = scenes == i
            counters = checker._filter.counters
            before = counters.copy()
            alone[mine] = checker._filter.paths(q0[mine], q1[mine], steps[mine], first)
            spent_alone += counters - before
        np.testing.assert_array_equal(together, alone)
        np.testing.assert_array_equal(spent, spent_alone)
        assert spent[COUNTERS.index("lane calls")] > 0
        assert 0 < (together >= 0).sum() < len(scenes)


@pytest.mark.parametrize("arm_name", ARMS)
def test_configuration_checks_answer_the_same_with_the_lanes_as_without(arm_name):
    checker = _checker(arm_name)
    arm, exact = make_arm(arm_name), checker._filter._exact
    rng = np.random.default_rng(7)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (300, arm.dof))
    lanes, counters = COUNTERS.index("lane samples"), checker._filter.counters
    function = int(exact[0, LANE_FUNCTION])
    answers = []
    for on in (function, 0):
        exact[0, LANE_FUNCTION] = on
        before = counters[lanes]
        answer = [checker.collides(q), checker.n_contacts(q)]
        for need in (1, 7, 40):  # rows in order until `need` are free; the rest −1
            out, how = np.empty(len(q), dtype=np.int64), np.empty(len(q), dtype=np.int8)
            bound_configurations(checker._filter._bound, np.zeros(1, dtype=np.int64), q, need,
                                 True, out, how)
            answer.append(out)
        answers.append(answer)
        assert (counters[lanes] > before) == bool(on)
    exact[0, LANE_FUNCTION] = function
    for with_lanes, without in zip(*answers, strict=True):
        np.testing.assert_array_equal(with_lanes, without)
    assert np.sum(answers[0][-1] == -1) > 0


@pytest.mark.parametrize("arm_name", ARMS)
def test_a_contact_the_lanes_prove_is_one_the_scalar_witnesses_prove(arm_name):
    # Lanes at one configuration each (no step asked): a lane proven in contact (−2) is in
    # contact by MuJoCo, and the scalar kernel, lanes off, proves it by a witness too.
    checker = _checker(arm_name)
    lanes, exact = checker._filter.lanes, checker._filter._exact
    arm, model = make_arm(arm_name), checker.model
    rng = np.random.default_rng(6)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (60 * LANES, arm.dof))
    steps = np.empty(len(q))
    start = np.tile(model.qpos0, (LANES, 1))
    npair = len(checker._filter.scene.pair_a)
    for block in range(0, len(q), LANES):
        start[:, : arm.dof] = q[block : block + LANES]
        steps[block : block + LANES] = lanes.bound(start, np.zeros_like(start), np.zeros(LANES),
                                                   np.zeros(LANES), np.zeros((LANES, npair)))[0]
    function = int(exact[0, LANE_FUNCTION])
    exact[0, LANE_FUNCTION] = 0
    _, how = checker._filter.collide_how(q)
    exact[0, LANE_FUNCTION] = function
    colliding = _checker(arm_name, backend="loop").collides(q)
    proven = steps == -2.0
    assert np.all(colliding[proven]) and np.all(how[proven] == BY_WITNESS)
    # Most contacts are proven in the lanes (the rest: skewers, cylinder rims, the
    # points' scallops go to the scalar kernel); a box has no contact points in the lanes
    # (the scalar kernel's witnesses prove its contacts).
    share = 0.8 if arm_name not in BOX_ARMS else 0.3
    assert proven.sum() > share * colliding.sum() > 0


#: A box carriage (three slides, two hinges) with a disc on a third hinge, and a box
#: shuttle on a slide, among a box rail, a post, a bar, a ball and the floor (geoms
#: named as their collision shapes: ``compile_spec`` names each box's mesh after it). The
#: disc and the slab are turned in their bodies (a geom's own rotation enters its axes);
#: the slab's lowest corner, 8.2 cm below its centre, slides from 2 cm into the floor to
#: 6 cm above it.
_CARRIAGE = """<mujoco><worldbody>
    <geom name="floor" type="plane" size="0 0 0.05"/>
    <geom name="rail" type="box" size="0.02 0.6 0.02" pos="0.3 0 0.3"/>
    <geom name="post" type="cylinder" size="0.05 0.3" pos="-0.3 0.2 0.3"/>
    <geom name="bar" type="capsule" fromto="-0.3 -0.3 0.1 0.3 -0.3 0.5" size="0.03"/>
    <geom name="ball" type="sphere" size="0.08" pos="0 0.35 0.2"/>
    <body name="carriage" pos="0 0 0.3">
      <joint name="x" type="slide" axis="1 0 0"/><joint name="y" type="slide" axis="0 1 0"/>
      <joint name="z" type="slide" axis="0 0 1"/><joint name="yaw" type="hinge" axis="0 0 1"/>
      <joint name="pitch" type="hinge" axis="0 1 0"/>
      <geom name="block" type="box" size="0.05 0.08 0.12"/>
      <body name="hub" pos="0 0 0.2"><joint name="roll" type="hinge" axis="1 0 0"/>
        <geom name="disc" type="cylinder" size="0.1 0.01" euler="0 35 0"/></body>
    </body>
    <body name="shuttle" pos="0 -0.5 0.102"><joint name="s" type="slide" axis="1 0 0.1"/>
      <geom name="slab" type="box" size="0.1 0.05 0.05" euler="20 0 40"/></body>
    </worldbody></mujoco>"""
#: The carriage's joint ranges drawn in the tests: the block reaches the rail, the floor,
#: the ball, the bar and the shuttle, the disc the floor and the rail.
_CARRIAGE_RANGE = np.array([[-0.3, 0.3], [-0.35, 0.35], [-0.3, 0.1], [-np.pi, np.pi],
                            [-0.6, 0.6], [-np.pi, np.pi], [-0.4, 0.4]])


def _carriage(backend: str = "compiled") -> CollisionChecker:
    # Its boxes compiled as the package compiles them: as their 8-vertex meshes, whose
    # collider MuJoCo decides as the geometry does (primitive box pairs: below).
    model = compile_spec(mujoco.MjSpec.from_string(_CARRIAGE))
    return CollisionChecker(model, dof=7, backend=backend)


def test_a_box_and_a_half_space_are_proven_free_only_where_they_are():
    # A moving box is bounded by its separation along the two boxes' face normals, any
    # geom by its exact height over a half-space (lanes.c: box_gaps, plane_gaps): every
    # configuration and every grid sample within a proven step is free by the exact loop.
    checker, loop = _carriage(), _carriage("loop")
    lanes, model = checker._filter.lanes, checker.model
    npair = len(checker._filter.scene.pair_a)
    rng = np.random.default_rng(8)
    lower, upper = _CARRIAGE_RANGE[:, 0], _CARRIAGE_RANGE[:, 1]
    proved = free_total = 0
    for _ in range(40):
        q0 = rng.uniform(lower, upper, (LANES, 7))
        q1 = np.clip(q0 + rng.uniform(-0.2, 0.2, q0.shape) * (upper - lower), lower, upper)
        start, change = np.tile(model.qpos0, (LANES, 1)), np.zeros((LANES, model.nq))
        start[:, :7] = q0
        steps = lanes.bound(start, change, np.zeros(LANES), np.zeros(LANES),
                            np.zeros((LANES, npair)))[0]
        free = ~loop.collides(q0)
        assert np.all(free[steps >= 0.0]), "a configuration proven free collides"
        proved, free_total = proved + int(np.sum(steps >= 0.0)), free_total + int(free.sum())
        n = checker.n_steps(q0, q1)
        mid = rng.integers(0, n + 1)
        change[:, :7] = q1 - q0
        rates = np.abs(q1 - q0) @ checker._filter.scene.pair_lever[0][:7]
        steps = lanes.bound(start, change, mid / n, rng.uniform(0.0, 0.3, LANES), rates)[0]
        for lane in np.flatnonzero(steps >= 0.0):
            samples = _within_step(q0, q1, n, mid, steps, lane)
            assert not loop.collides(samples).any(), "a sample within a proven step collides"
    assert proved > 0.9 * free_total > 0


def test_a_carriage_beside_its_rail_is_proven_free_where_its_covers_cannot():
    # The block's +x face 13 mm from the rail's, parallel (the checker's margin: 10 mm):
    # its cover spheres reach past the face and prove nothing; the face normals prove it.
    checker = _carriage()
    lanes, model, scene = checker._filter.lanes, checker.model, checker._filter.scene
    q = np.array([0.217, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert not _carriage("loop").collides(q[None])[0]
    start, centres, radii = lanes.covers
    block = next(s for s in range(len(scene.slot_type))
                 if model.geom(int(scene.slot_geom[s])).name == "block")
    mine = slice(start[block], start[block + 1])
    world = centres[mine] + np.array([0.217, 0.0, 0.3])  # the carriage's frame: a shift
    outside = np.maximum(np.abs(world - [0.3, 0.0, 0.3]) - [0.02, 0.6, 0.02], 0.0)
    assert np.min(np.linalg.norm(outside, axis=1) - radii[mine]) < 0.010  # covers: not free
    rows = np.tile(model.qpos0, (LANES, 1))
    rows[:, :7] = q
    steps = lanes.bound(rows, np.zeros_like(rows), np.zeros(LANES), np.zeros(LANES),
                        np.zeros((LANES, len(scene.pair_a))))[0]
    assert np.all(steps == 0.0)


def test_two_primitive_boxes_are_proven_free_by_their_bounding_spheres_alone():
    # MuJoCo's box–box collider reports these two primitive boxes in contact 0.0100 m
    # apart (margin 0.01) where they lie 0.0112 m apart (mj_geomDistance): a true bound
    # (cells, separation) would call them free. The lanes leave such a pair to the
    # bounding spheres, MuJoCo's own broad phase, so every verdict stays MuJoCo's.
    model = mujoco.MjModel.from_xml_string("""<mujoco><worldbody>
        <geom type="box" size="0.076747 0.007381 0.126647"
              pos="-0.01057812 -0.236703704 0.052470344"
              quat="0.448971121 0.841397236 0.097466746 -0.284562572"/>
        <body pos="-0.188101789 -0.147218548 0.110485935"
              quat="0.53043568 -0.806170247 -0.255815136 -0.057324854">
          <joint type="slide" axis="1 0 0"/>
          <geom type="box" size="0.116791 0.054935 0.036506"/></body>
        </worldbody></mujoco>""")
    checker, loop = CollisionChecker(model, dof=1), CollisionChecker(model, dof=1, backend="loop")
    assert primitive_box_pairs(checker.model, checker._filter.scene).tolist() == [True]
    x = np.linspace(-0.03, 0.01, 81)[:, None]
    expected = loop.collides(x)
    assert expected[x[:, 0] == 0.0].all() and not expected.all()  # MuJoCo's contact above
    np.testing.assert_array_equal(checker.collides(x), expected)
    # Paths against MuJoCo at every grid sample (the loop backend's advancement skips
    # samples by mj_geomDistance, which does not see the collider's contacts outside).
    every = CollisionChecker(model, dof=1, backend="batch")
    q0, q1 = np.full((64, 1), -0.02), np.linspace(0.0, 0.02, 64)[:, None]
    collides, first = checker.check_paths(q0, q1)
    expected, expected_first = every.check_paths(q0, q1)
    np.testing.assert_array_equal(collides, expected)
    np.testing.assert_array_equal(first, expected_first)
    assert expected.all() and not loop.check_paths(q0, q1)[0].all()


def _rod_and_wall(wall_x: float) -> CollisionChecker:
    """A capsule rod turning about a vertical hinge through a thin primitive box wall."""
    model = mujoco.MjModel.from_xml_string(f"""<mujoco><worldbody>
        <geom name="wall" type="box" size="0.02 0.3 0.3" pos="{wall_x} 0 0.5" margin="0.005"/>
        <body name="link" pos="0 0 0.5"><joint name="j" type="hinge" axis="0 0 1"/>
        <geom name="rod" type="capsule" fromto="0.2 0 0 1.0 0 0" size="0.02"
              margin="0.005"/></body></worldbody></mujoco>""")
    return CollisionChecker(model, dof=1, backend="compiled")


@pytest.mark.parametrize("wall_x", [0.6, 0.99])  # the rod through the wall; its end in it
def test_the_lanes_never_prove_a_skewering_rod_in_contact_where_mujoco_finds_none(wall_x):
    # MuJoCo's capsule–box collider misses a capsule whose axis passes through a box with
    # both ends outside: the lanes prove a capsule–box contact only where the axis misses
    # the box (every point farther than half their spacing) or an end is inside it.
    checker = _rod_and_wall(wall_x)
    model, data = checker.model, mujoco.MjData(checker.model)
    angles = np.linspace(-0.7, 0.7, 40 * LANES)
    steps = np.concatenate([checker._filter.lanes.bound(
        block[:, None], np.zeros((LANES, 1)), np.zeros(LANES), np.zeros(LANES),
        np.zeros((LANES, 1)))[0] for block in angles.reshape(-1, LANES)])
    contacts = np.empty(len(angles), dtype=int)
    for i, angle in enumerate(angles):
        data.qpos[0] = angle
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        contacts[i] = data.ncon
    proven = steps == -2.0
    assert proven.sum() > 20 and np.all(contacts[proven] > 0)
    if wall_x == 0.6:  # the rod crosses the wall: MuJoCo misses some of those overlaps
        crossing = np.abs(np.tan(angles)) * 0.6 < 0.3 - 0.02
        assert np.sum(crossing & (contacts == 0)) > 20


def test_an_ellipsoid_is_held_by_cells_within_its_bounding_sphere_and_checked_in_the_lanes():
    # Its container is its box (0.1 × 0.1 × 0.01), its bounding radius the ellipsoid's
    # (0.1), which the lanes' rounding allowance assumes holds every cover. By hand: 4×4×1
    # cells would reach 0.0267 past the box but their corner cells' centres lie 0.106 from
    # the centre; of the cuts within 0.1, 3×3×1 reaches least (0.0382; 2×7×1 0.0429, 3×3×2
    # 0.0424): nine spheres of radius √(2·(0.1/3)² + 0.01²).
    model = mujoco.MjModel.from_xml_string("""<mujoco><worldbody>
        <geom name="wall" type="box" size="0.02 0.3 0.3" pos="0.6 0 0.5"/>
        <body name="link" pos="0 0 0.5"><joint name="j" type="hinge" axis="0 0 1"/>
        <geom name="disc" type="ellipsoid" size="0.1 0.1 0.01" pos="0.5 0 0"/>
        </body></worldbody></mujoco>""")
    checker, loop = (CollisionChecker(model, dof=1, backend=b) for b in ("compiled", "loop"))
    lanes = checker._filter.lanes
    start, centres, radii = lanes.covers
    assert lanes.address != 0 and start.tolist() == [0, 0, 9]
    grid = [-0.2 / 3, 0.0, 0.2 / 3]
    expected = [[0.5 + x, y, 0.0] for x in grid for y in grid]
    np.testing.assert_allclose(centres, expected, rtol=0, atol=1e-15)
    radius = np.sqrt(2 * (0.1 / 3) ** 2 + 0.01**2)
    np.testing.assert_allclose(radii, radius * (1 + 1e-12) + 1e-12, rtol=1e-15)  # rounding
    q0 = np.linspace(-1.0, 1.0, 41)[:, None]
    q1 = -q0[::-1]
    before = checker._filter.counters[COUNTERS.index("lane samples")]
    collides, first = checker.check_paths(q0, q1)
    assert checker._filter.counters[COUNTERS.index("lane samples")] > before
    loop_collides, loop_first = loop.check_paths(q0, q1)
    np.testing.assert_array_equal(collides, loop_collides)
    np.testing.assert_array_equal(first, loop_first)
    assert 0 < collides.sum() < len(q0)


def test_a_box_with_no_cut_within_the_bounding_radius_takes_the_bounding_sphere():
    # Only a geom its bounding sphere holds asks for that (the cube's eight cells reach
    # 0.0866 from its centre).
    assert box_cells(np.array([0.1, 0.1, 0.1]), 0.05) == [((0.0, 0.0, 0.0), 0.05)]


def test_a_scene_whose_measured_geom_has_no_covers_leaves_the_filter_without_lanes():
    # Every moving geom MuJoCo allows has covers; were one without (a kind the lanes do
    # not know), its pairs could not be bounded in the lanes.
    scene = _checker("ur5e")._filter.scene
    start = _checker("ur5e")._filter.lanes.covers[0]
    assert usable(scene, start)
    first = int(scene.pair_a[0])
    owned = np.diff(start)
    owned[first] = 0
    assert not usable(scene, np.concatenate([[0], np.cumsum(owned)]))


def test_without_a_c_compiler_the_lanes_say_so_and_stay_off(monkeypatch):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    with pytest.warns(RuntimeWarning, match="did not compile"):
        assert library.__wrapped__() is None



@pytest.mark.parametrize("name", ["PATHS_FIELDS", "P_MID", "PATHS_SCALAR"])
def test_a_path_search_state_that_disagrees_with_lanes_c_is_refused(monkeypatch, name):
    # The numba loop lays out lanes.c's Paths struct by the constants of lanes.py; a kernel
    # whose struct is laid out otherwise is an error, not a search reading wrong fields.
    from ikbranch_gym.envs.models.filter import lanes

    assert library() is not None
    monkeypatch.setattr(lanes, name, getattr(lanes, name) + 1)
    with pytest.raises(RuntimeError, match=r"lays its Paths out as .* 170, 186, 1\)"):
        library.__wrapped__()

def _rod_and_ball(offset: float) -> tuple[CollisionChecker, np.ndarray, np.ndarray]:
    """A capsule rod sliding along its axis (x) toward a ball ahead of its end and beside
    its axis, the whole cell ``offset`` metres from the world's origin: while the ball is
    ahead of the end, the rod's end cap cover measures the distance exactly, so the lanes'
    bound there is the distance itself, up to their rounding. The ball's x lies just past
    the middle between two single-precision numbers, so that rounding it moves it away
    from the rod by almost half a unit in the last place (30 µm at 500 m). Returns the
    checker, the rod end at q = 0 and the ball's centre."""
    end = np.array([offset + 1.0, 0.0, 0.5])
    ball = end + np.array([0.13, 0.075, 0.0])
    below = float(np.float32(ball[0]))
    ball[0] = below + 0.51 * float(np.spacing(np.float32(below)))
    assert float(np.float32(ball[0])) > ball[0]  # rounds up, away from the rod
    x, y, z = (repr(float(c)) for c in ball)
    model = mujoco.MjModel.from_xml_string(f"""<mujoco><worldbody>
        <geom name="ball" type="sphere" size="0.05" pos="{x} {y} {z}" margin="0.005"/>
        <body name="carriage" pos="{offset!r} 0 0.5">
          <joint name="x" type="slide" axis="1 0 0" range="-1 1"/>
          <geom name="rod" type="capsule" fromto="0.2 0 0 1.0 0 0" size="0.02"
                margin="0.005"/></body></worldbody></mujoco>""")
    return CollisionChecker(model, dof=1, backend="compiled"), end, ball


@pytest.mark.parametrize("offset", [0.0, 500.0])
def test_the_lanes_single_precision_proves_nothing_within_its_rounding(offset):
    # The covers' and contact points' distances run in single precision: a lane proves
    # the pair apart only where its distance exceeds the margins, and in contact only where
    # it is below them, at slides across that boundary in steps far below a unit in the
    # last place (where the ball's and the rod end's rounding add up against the proof),
    # and it does prove them a few times the stated rounding bound away.
    checker, end, ball = _rod_and_ball(offset)
    lanes = checker._filter.lanes
    assert lanes.address
    margin = 0.01  # the two geoms' margins
    rod_centre, rod_radius = offset + 0.6, 0.4 + 0.02
    rounding = 128 * 2.0**-24 * (rod_centre + 0.2 + abs(ball[0]) + 2 * rod_radius + 0.05)

    def distance(q: np.ndarray) -> np.ndarray:  # rod surface to ball surface, in double
        tip = np.stack([end[0] + q, np.full_like(q, end[1]), np.full_like(q, end[2])], 1)
        return np.linalg.norm(ball - tip, axis=1) - 0.02 - 0.05

    # The slide at which the distance equals the margins (bisection in double; the ball
    # is still ahead of the rod's end there).
    lo, hi = 0.0, 0.13
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if distance(np.array([mid]))[0] > margin else (lo, mid)
    assert ball[0] - (end[0] + lo) > 0.02
    unit = float(np.spacing(np.float32(end[0])))  # a unit in the last place at the rod end
    q = np.concatenate([lo + np.linspace(-3 * unit, 3 * unit, 40 * LANES),
                        np.linspace(0.0, 0.13, 8 * LANES)])
    steps = np.concatenate([lanes.bound(block[:, None], np.zeros((LANES, 1)),
                                        np.zeros(LANES), np.zeros(LANES),
                                        np.zeros((LANES, 1)))[0]
                            for block in q.reshape(-1, LANES)])
    gaps = distance(q)
    apart, touching = steps >= 0.0, steps == -2.0
    assert np.all(gaps[apart] > margin), np.min(gaps[apart] - margin)
    assert np.all(gaps[touching] < margin), np.max(gaps[touching] - margin)
    clear = gaps > margin + 2 * rounding
    assert clear.sum() >= LANES and np.all(apart[clear])
    if not offset:
        inside = gaps < margin - 2 * rounding - 1e-4  # the witness tolerance, and more
        assert inside.sum() >= LANES and np.all(touching[inside])
