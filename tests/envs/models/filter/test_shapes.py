"""Pair bounds never exceed the distance."""

from __future__ import annotations

import itertools
import math

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import CollisionChecker, build_model
from ikbranch_gym.envs.models.builders import add_part, compile_spec
from ikbranch_gym.envs.models.filter import kernels, layout, shapes
from ikbranch_gym.envs.models.filter import tree as kinematics
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
                                       slot_type[b], *frame_b, kernels._size(slot_size, b),
                                       math.inf)
            # A bound only has to be right about separation (it proves "farther than
            # the margin"); for a penetrating pair it only has to be ≤ 0.
            assert bound <= max(distance, 0.0) + 1e-9, (model.geom(int(g1)).name,
                                                        model.geom(int(g2)).name)
            sphere = shapes._bound_pair(layout.SPHERE, frame_a[0], frame_a[1],
                                        (slot_radius[a], 0.0, 0.0), slot_type[b], *frame_b,
                                        kernels._size(slot_size, b), math.inf)
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


def _place_bodies(model: mujoco.MjModel, names, rng, scale: float) -> None:
    """Each named body at a random place (normal, ``scale`` m) and rotation."""
    for name in names:
        rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        rotation *= np.sign(np.linalg.det(rotation))
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rotation.ravel())
        model.body(name).pos, model.body(name).quat = rng.normal(scale=scale, size=3), quat


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
        _place_bodies(model, ("one", "two"), rng, 0.4)
        mujoco.mj_kinematics(model, data)
        frames = [(tuple(data.geom_xpos[g]), tuple(data.geom_xmat[g]), *model.geom_aabb[g][3:])
                  for g in geoms]
        distance = mujoco.mj_geomDistance(model, data, *geoms, 10.0, None)
        (c1, r1, *h1), (c2, r2, *h2) = frames
        bound = shapes._box_box(c1, r1, *h1, c2, r2, *h2, math.inf)
        assert bound <= max(distance, 0.0) + 1e-7
        close += 0 < distance < 0.2
    assert close > 20




# ------------------------------------------------------------------------ witnesses
#: Geoms of the witness study: MuJoCo type, size (sizes of meshes: a box's half-sizes).
_SHAPES = {
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "mesh": mujoco.mjtGeom.mjGEOM_MESH,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "ellipsoid": mujoco.mjtGeom.mjGEOM_ELLIPSOID,
}


def _pair_model(first: str, second: str, rng) -> mujoco.MjModel:
    """Two bodies on slide joints (moving: frames recomputed), one geom each, margins
    0.005 (a pair margin of 0.01), the checker's options."""
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_MIDPHASE
    for name, shape in (("one", first), ("two", second)):
        body = spec.worldbody.add_body()
        body.name = name
        body.add_joint().type = mujoco.mjtJoint.mjJNT_SLIDE
        half = rng.uniform(0.03, 0.3, size=3)
        geom = body.add_geom()
        geom.name, geom.margin, geom.gap = name, 0.005, 0.0
        if shape == "mesh":
            corners = np.array(list(itertools.product((-1, 1), repeat=3))) * half
            spec.add_mesh(name=f"{name}_box", uservert=corners.ravel().tolist())
            geom.type, geom.meshname = _SHAPES["mesh"], f"{name}_box"
        else:
            geom.type, geom.size = _SHAPES[shape], half
    return spec.compile()


@pytest.mark.parametrize(("first", "second"), [
    (a, b) for i, a in enumerate(_SHAPES) for b in list(_SHAPES)[i:]])
def test_inner_shapes_closer_than_the_margin_are_mujocos_contacts(first, second):
    # The witness promise (layout.inner, kernels._witnessed): wherever two inner shapes
    # are closer than the pair's margin less the tolerance, mj_collision reports a
    # contact — for every collider the scenes use; primitive box pairs and a capsule
    # skewering a primitive box are excluded, as the filter excludes them.
    from ikbranch_gym.envs.models.filter.layout import WITNESS_TOLERANCE

    rng = np.random.default_rng([list(_SHAPES).index(first), list(_SHAPES).index(second)])
    model = _pair_model(first, second, rng)
    data = mujoco.MjData(model)
    geoms = [model.geom(name).id for name in ("one", "two")]
    inner = [layout.inner(model, g) for g in geoms]
    boxes = first == second == "box"
    skewer_pair = {first, second} == {"capsule", "box"}
    witnessed = contacts = 0
    for _ in range(2000):
        _place_bodies(model, ("one", "two"), rng, 0.2)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        contacts += data.ncon > 0
        frames = [(tuple(data.geom_xpos[g] + data.geom_xmat[g].reshape(3, 3)
                         @ model.geom_aabb[g][:3] * (model.geom_type[g] == _SHAPES["mesh"])),
                   tuple(data.geom_xmat[g])) for g in geoms]
        (ka, sa), (kb, sb) = inner
        args = (ka, *frames[0], tuple(sa), kb, *frames[1], tuple(sb))
        distance = shapes._inner_distance(*args)
        if distance < 0.01 - WITNESS_TOLERANCE and not boxes:
            if skewer_pair and shapes._skewers(*args):
                continue
            witnessed += 1
            assert data.ncon > 0, (first, second, distance)
    assert boxes or witnessed > 50
    assert contacts > 50


def test_box_box_distance_is_exact():
    rng = np.random.default_rng(32)
    for _ in range(300):
        boxes = []
        for _ in range(2):
            rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
            boxes.append((rng.normal(scale=0.3, size=3), rotation, rng.uniform(0.05, 0.4, 3)))
        (c1, r1, h1), (c2, r2, h2) = boxes
        value = shapes._box_box_distance(tuple(c1), tuple(r1.ravel()), *h1, tuple(c2),
                                         tuple(r2.ravel()), *h2)
        # Dense points of box 1 (its surface grid) against box 2, exactly: an upper bound.
        grid = np.array(list(itertools.product(np.linspace(-1, 1, 9), repeat=3)))
        points = c1 + (grid * h1) @ r1.T
        local = (points - c2) @ r2
        dense = np.linalg.norm(np.maximum(np.abs(local) - h2, 0.0), axis=1).min()
        assert value <= dense + 1e-12
        # And never below the separating-axis lower bound.
        bound = shapes._box_box(tuple(c1), tuple(r1.ravel()), *h1, tuple(c2), tuple(r2.ravel()),
                                *h2, math.inf)
        assert value >= bound - 1e-12
        if bound > 0:
            assert value == pytest.approx(dense, abs=0.06 * h1.max())


def _point_cylinder(points, r, h):
    """Exact distances of points (cylinder frame) from the solid cylinder."""
    rho = np.hypot(points[:, 0], points[:, 1])
    radial = np.maximum(rho - r, 0.0)
    axial = np.maximum(np.abs(points[:, 2]) - h, 0.0)
    return np.hypot(radial, axial)


def test_segment_cylinder_bound_is_below_and_within_a_micrometre_of_the_distance():
    # Against the distance of 20,001 points along the segment (at most |pq| / 40,000
    # above the exact one): every bound at most that, and at most 1 µm below it. Segments
    # over the rims, across the flat ends, beside the side, through the cylinder, and
    # single points.
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 1.0, 20_001)[:, None]
    checked = 0
    for trial in range(600):
        r, h = rng.uniform(0.02, 0.3, size=2)
        centre = rng.normal(size=3)
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        rot = q * np.sign(np.linalg.det(q))  # a rotation
        local = rng.normal(scale=(r + h), size=(2, 3))
        if trial % 5 == 0:
            local[1] = local[0]  # a point
        p, e = centre + rot @ local[0], centre + rot @ local[1]
        bound = shapes._segment_cylinder(*p, *e, tuple(centre), tuple(rot.ravel()), r, h,
                                         -math.inf, math.inf)
        brute = _point_cylinder(local[0] + t * (local[1] - local[0]), r, h).min()
        length = np.linalg.norm(local[1] - local[0])
        assert bound <= brute + 1e-12, trial
        assert bound >= brute - length / 40_000 - 1e-6, trial
        checked += brute > 0.0
        # Told it may stop at ``enough``: still a bound, and it reaches ``enough`` where
        # the distance is clear of it; told a ``floor``: still a bound.
        for enough in (0.5 * brute, brute - 1e-5, brute + 1e-3):
            early = shapes._segment_cylinder(*p, *e, tuple(centre), tuple(rot.ravel()), r,
                                             h, -math.inf, enough)
            assert early <= brute + 1e-12, trial
            if brute - length / 40_000 - 1e-6 >= enough:
                assert early >= enough, trial
        floored = shapes._segment_cylinder(*p, *e, tuple(centre), tuple(rot.ravel()), r, h,
                                           brute - 1e-4, math.inf)
        assert floored <= brute + 1e-12, trial
    assert checked > 300


#: Partners of the cylinder witness at the margin's edge: name -> (MuJoCo type, size), the
#: cylinder the partner meets (radius, half-height). The first four are UR5e-v3's pairs
#: that the inner shapes alone left to MuJoCo most often (forearm–flange; shoulder
#: housing, upper arm and elbow housing against the clutter's cylinders).
_AXIS_CASES = {
    "forearm–flange": ("capsule", (0.0409, 0.145), (0.0327, 0.0349)),
    "housing–flat cylinder": ("capsule", (0.0654, 0.1075), (0.1474, 0.05)),
    "upper arm–cylinder r = h": ("capsule", (0.049, 0.2125), (0.05, 0.05)),
    "elbow housing–cylinder": ("capsule", (0.0531, 0.0666), (0.0767, 0.05)),
    "sphere–tall cylinder": ("sphere", (0.04,), (0.03, 0.2)),
    "cylinder–cylinder": ("cylinder", (0.03, 0.09), (0.06, 0.04)),
    "ellipsoid–cylinder": ("ellipsoid", (0.03, 0.05, 0.07), (0.05, 0.12)),
}


def _axis_gap(ends: np.ndarray, r: float, h: float) -> tuple[float, np.ndarray]:
    """The least distance of the segment ``ends`` (cylinder frame) from the solid cylinder,
    and the point of the segment where it is least: dense, then refined by scipy (the
    distance is convex along the segment)."""
    from scipy.optimize import minimize_scalar

    def at(t):
        return ends[0] + t * (ends[1] - ends[0])

    t = np.linspace(0.0, 1.0, 2001)
    values = _point_cylinder(at(t[:, None]), r, h)
    i = int(values.argmin())
    lo, hi = t[max(i - 1, 0)], t[min(i + 1, len(t) - 1)]
    best = minimize_scalar(lambda s: _point_cylinder(at(s)[None], r, h)[0], bounds=(lo, hi),
                           method="bounded", options={"xatol": 1e-13})
    s = float(best.x) if best.fun < values[i] else float(t[i])
    return float(_point_cylinder(at(s)[None], r, h)[0]), at(s)


def _axis_pair(case: str):
    """The model of a case of ``_AXIS_CASES``: the cylinder fixed at the origin, the partner
    on a free joint, margins 0.005 (a pair margin of 0.01); with its ``MjData``, the
    partner's inner kind and size, and the cylinder's (radius, half-height)."""
    shape, size, (r, h) = _AXIS_CASES[case]
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    cylinder = spec.worldbody.add_body().add_geom()
    cylinder.name, cylinder.type, cylinder.size = "cylinder", _SHAPES["cylinder"], [r, h, 0.0]
    partner_body = spec.worldbody.add_body()
    partner_body.name = "partner"
    partner_body.add_freejoint()
    partner = partner_body.add_geom()
    partner.name, partner.type = "partner", _SHAPES[shape]
    partner.size = [*size, 0.0, 0.0][:3]
    for geom in (cylinder, partner):
        geom.margin, geom.gap = 0.005, 0.0
    model = spec.compile()
    kind, inner_size = layout.inner(model, model.geom("partner").id)
    assert kind in (layout.SPHERE, layout.CAPSULE)
    return model, mujoco.MjData(model), kind, inner_size, (r, h)


def _axis_verdicts(model, data, kind, inner_size, r, h, centre, rotation, limit):
    """(the witness, MuJoCo's verdict with multi-CCD on, off) for the partner placed at
    ``centre`` with ``rotation``."""
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rotation.ravel())
    data.qpos[:3], data.qpos[3:] = centre, quat
    mujoco.mj_kinematics(model, data)
    frames = [(tuple(data.geom_xpos[g]), tuple(data.geom_xmat[g]))
              for g in (model.geom("partner").id, model.geom("cylinder").id)]
    witness = shapes._axis_in_cylinder(kind, *frames[0], tuple(inner_size), *frames[1],
                                       (r, h, 0.0), limit)
    verdicts = []
    for multi in (True, False):
        model.opt.disableflags = 0 if multi else int(mujoco.mjtDisableBit.mjDSBL_MULTICCD)
        mujoco.mj_collision(model, data)
        verdicts.append(data.ncon > 0)
    model.opt.disableflags = 0
    return witness, *verdicts


def _axis_rotation(axis: np.ndarray, rng) -> np.ndarray:
    """A rotation whose z column is ``axis``."""
    rotation = np.linalg.qr(np.c_[axis, rng.normal(size=(3, 2))])[0]
    return rotation[:, [1, 2, 0]] * np.sign(np.linalg.det(rotation))


@pytest.mark.parametrize("case", list(_AXIS_CASES))
def test_a_partners_axis_near_a_cylinder_is_mujocos_contact_at_the_witness_limit(case):
    # The cylinder witness (shapes._axis_in_cylinder, kernels._witnessed): the partner's
    # inner sphere or capsule, measured against the cylinder itself, proves a contact
    # wherever it comes closer than the margin less the tolerance. Placed so that its
    # exact value sits 10 nm inside that limit, the witness fires and MuJoCo reports the
    # contact (multi-CCD on, as the checker runs it, and off); 10 nm outside, it does not
    # fire; 15 µm outside the margin, where the inner shape is the partner itself, MuJoCo
    # reports no contact either (the placements sit at MuJoCo's edge). Half the
    # placements lie across a flat end, nearly parallel to it.
    from ikbranch_gym.envs.models.filter.layout import WITNESS_TOLERANCE

    model, data, kind, inner_size, (r, h) = _axis_pair(case)
    radius, half = inner_size[0], (inner_size[1] if kind == layout.CAPSULE else 0.0)
    exact = _AXIS_CASES[case][0] in ("capsule", "sphere")  # the inner shape is the partner
    limit = 0.01 - WITNESS_TOLERANCE
    targets = ((limit - 1e-8, True, True), (limit + 1e-8, False, True if exact else None),
               (0.01 + 1.5e-5, False, False if exact else None))
    rng = np.random.default_rng(list(_AXIS_CASES).index(case))
    proved = 0
    for trial in range(150):
        if trial % 2:  # across a flat end, the axis within ~6° of it
            phi = rng.uniform(0.0, 2.0 * np.pi)
            axis = np.array([math.cos(phi), math.sin(phi), rng.uniform(-0.1, 0.1)])
            centre = np.r_[rng.uniform(-r, r, 2), rng.choice([-1.0, 1.0]) * (h + radius)]
        else:
            axis, centre = rng.normal(size=3), rng.normal(scale=0.06, size=3)
        rotation = _axis_rotation(axis / np.linalg.norm(axis), rng)
        for target, fires, reported in targets:
            c = centre.copy()
            for _ in range(8):  # along the normal at the nearest point, until U = target
                ends = np.array([c - half * rotation[:, 2], c + half * rotation[:, 2]])
                gap, point = _axis_gap(ends, r, h)
                if gap <= 0.0:
                    break
                rho = math.hypot(point[0], point[1])
                near = np.r_[point[:2] * min(1.0, r / rho), np.clip(point[2], -h, h)]
                normal = (point - near) / np.linalg.norm(point - near)
                c = c + (target + radius - gap) * normal
            ends = np.array([c - half * rotation[:, 2], c + half * rotation[:, 2]])
            if abs(_axis_gap(ends, r, h)[0] - radius - target) > 1e-10:
                continue  # the axis ended inside (a deep placement): not at the edge
            witness, *mujocos = _axis_verdicts(model, data, kind, inner_size, r, h, c,
                                               rotation, limit)
            assert witness == fires, (case, trial, target)
            if reported is not None:
                assert mujocos == [reported, reported], (case, trial, target)
            proved += fires
    assert proved > 80


@pytest.mark.parametrize("case", list(_AXIS_CASES))
def test_a_partners_axis_deep_in_a_cylinder_is_mujocos_contact(case):
    # Most contacts the cylinder witness proves are deep ones at the rims, which MuJoCo's
    # convex collider settles by its penetration search: wherever the witness fires on a
    # random placement around the cylinder, MuJoCo reports the contact.
    from ikbranch_gym.envs.models.filter.layout import WITNESS_TOLERANCE

    model, data, kind, inner_size, (r, h) = _axis_pair(case)
    rng = np.random.default_rng(100 + list(_AXIS_CASES).index(case))
    fired = 0
    for trial in range(600):
        axis = rng.normal(size=3)
        rotation = _axis_rotation(axis / np.linalg.norm(axis), rng)
        reach = inner_size[0] + (inner_size[1] if kind == layout.CAPSULE else 0.0)
        centre = rng.uniform(-1.0, 1.0, size=3) * (r + reach, r + reach, h + reach)
        witness, *mujocos = _axis_verdicts(model, data, kind, inner_size, r, h, centre,
                                           rotation, 0.01 - WITNESS_TOLERANCE)
        if witness:
            assert mujocos == [True, True], (case, trial)
            fired += 1
    assert fired > 60


def test_axis_in_cylinder_is_the_least_distance_along_the_axis_below_the_limit():
    # Against 20,001 points along the axis (at most |pq| / 40,000 above the exact least
    # distance): the witness fires exactly where that least distance less the radius is
    # below the limit, away from a band of that sampling's error around it. Spheres
    # (a point axis), axes over the rims, across the flat ends, beside the side, through
    # the cylinder.
    rng = np.random.default_rng(8)
    t = np.linspace(0.0, 1.0, 20_001)[:, None]
    fired = quiet = 0
    for trial in range(600):
        r, h = rng.uniform(0.02, 0.3, size=2)
        centre = rng.normal(size=3)
        rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        radius, half = rng.uniform(0.01, 0.1), (0.0 if trial % 5 == 0 else rng.uniform(0.0, 0.3))
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        own, _ = np.linalg.qr(np.c_[axis, rng.normal(size=(3, 2))])
        own = own[:, [1, 2, 0]] * np.sign(np.linalg.det(own))  # z along the axis
        middle = centre + rot @ rng.normal(scale=r + h + radius, size=3)
        ends = np.array([middle - half * own[:, 2], middle + half * own[:, 2]])
        local = (ends - centre) @ rot
        least = _point_cylinder(local[0] + t * (local[1] - local[0]), r, h).min() - radius
        error = 2 * half / 40_000 + 1e-9
        limit = least + rng.choice([-1.0, 1.0]) * rng.uniform(2 * error, 0.05)
        kind = layout.SPHERE if half == 0.0 else layout.CAPSULE
        witness = shapes._axis_in_cylinder(kind, tuple(middle), tuple(own.ravel()),
                                           (radius, half, 0.0), tuple(centre),
                                           tuple(rot.ravel()), (r, h, 0.0), limit)
        assert witness == (least < limit), trial
        fired += witness
        quiet += not witness
    assert fired > 200 and quiet > 200
