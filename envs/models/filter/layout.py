"""Model -> flat arrays: what the filter's kernels read of a compiled MuJoCo model.

:func:`compile_scene` reads the kinematic tree (hinge and slide joints, body offsets) and
every collision geom that ``mj_collision`` may test
(:func:`~envs.models.collision.candidate_pairs`) as a *container* that holds it (spheres,
capsules and boxes as themselves, a convex mesh as its bounding box, a cylinder as both
the capsule and the box around it, an ellipsoid as its box, a plane as its half-space),
each inside a bounding sphere, and per pair the lever arms that bound how fast its
distance can change (per geom, over all configurations; ``docs/models.md``). No per-arm
code: every model ``envs.models`` builds gets it. :func:`refresh_static` follows static
geoms that moved (the per-episode clutter).

Beside the container, each geom has an *inner* shape that it holds (:func:`inner`): itself
where it is a sphere, capsule, box, a mesh whose hull is its bounding box, or a plane; the
capsule inside a cylinder (the square prism inside a disc), the sphere inside an
ellipsoid. Two inner shapes closer than a pair's margin (less ``WITNESS_TOLERANCE``) prove
the pair in contact, and so does an inner sphere or capsule that close to a cylinder
itself: MuJoCo's colliders report it (``docs/models.md`` has the study of MuJoCo's
colliders behind this). Two
colliders do not: a pair of primitive boxes (which misses some contacts inside the margin
and reports some outside it) gets no witness, and a primitive capsule–box pair none where
the capsule's axis passes through the box with both ends outside it (a "skewer", which
that collider misses although the shapes overlap).

Several scenes of one model (the sub-envs of a vector env, each with its own clutter)
share everything but the static geoms' places and sizes: those fields (``PER_SCENE``)
carry a leading scene axis, of length 1 for a filter of its own, and a filter that joins
a stack (``envs.models.filter.FilterStack``) reads and writes its row of the stack's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ikbranch_gym.envs.jit import njit

#: Reported distances are trusted only up to this (m): a pair counts as proven free only
#: when its lower bound exceeds the contact margin by this much.
DISTANCE_TOLERANCE = 1e-6

#: Inner shapes are trusted up to this (m): a pair whose inner shapes come closer than its
#: contact margin less this is in contact as MuJoCo reports contacts.
WITNESS_TOLERANCE = 1e-5

#: MuJoCo's default iterations and tolerance of its convex collider: a model whose collider
#: stops sooner gets no witnesses.
CCD_ITERATIONS, CCD_TOLERANCE = 35, 1e-6

#: A pair (kind) whose static partner lies beyond the moving geom's reach: skipped.
OUT_OF_REACH = 3
#: Container shapes (codes shared with the kernels).
SPHERE, CAPSULE, BOX, CYLINDER, PLANE, UNBOUNDED = 0, 1, 2, 3, 4, 5
#: A disc's inner square prism: half-sides radius / √2 (its corners on the rim).
_HALF_SQRT2 = math.sqrt(0.5)
#: The inner shape of a geom that has none the kernels can measure.
NO_INNER = -1
#: Joint type codes, MuJoCo's own.
_SLIDE, _HINGE = int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE)


@dataclass(frozen=True, eq=False)
class CompiledScene:
    """Everything the kernels read, as flat arrays (see the module docstring).

    Tree: ``body_*`` (nbody), ``jnt_*`` (njnt), ``qpos0``. Geoms ("slots": only those of
    candidate pairs): body, shape frame in the body frame (for static slots: in the world,
    fixed), container type, size, bounding radius about the shape centre, inner shape and
    its size (in the container's frame). Pairs: the two slots (a static one always
    second), the contact margin, the distance under which inner shapes prove a contact
    (−inf: no witness for the pair), whether MuJoCo collides the pair as a primitive
    capsule and box (no witness for a skewer), and per joint the lever arm that bounds the
    rate of change of the pair's distance (m per rad, 1 for a slide; ``pair_lever``
    (njnt, P), per joint for a path's rates in one pass: ``pair_lever_own`` without the
    symmetries of static partners, which depend on where they lie, and ``jnt_line``, the
    world-fixed axis lines that such symmetries are about). The fields in ``PER_SCENE``
    have a leading scene axis (module docstring).
    """

    body_parent: np.ndarray
    body_pos: np.ndarray
    body_rot: np.ndarray
    body_jntadr: np.ndarray
    body_jntnum: np.ndarray
    body_flags: np.ndarray
    jnt_type: np.ndarray
    jnt_qposadr: np.ndarray
    jnt_pos: np.ndarray
    jnt_axis: np.ndarray
    jnt_axis_code: np.ndarray
    qpos0: np.ndarray
    body_xpos: np.ndarray
    body_xmat: np.ndarray
    slot_geom: np.ndarray
    slot_body: np.ndarray
    slot_inner: np.ndarray
    slot_inner_size: np.ndarray
    pair_contact: np.ndarray
    pair_skewer: np.ndarray
    slot_static: np.ndarray
    slot_pos: np.ndarray
    slot_rot: np.ndarray
    slot_type: np.ndarray
    slot_size: np.ndarray
    slot_radius: np.ndarray
    pair_a: np.ndarray
    pair_b: np.ndarray
    pair_kind: np.ndarray
    pair_fixed: np.ndarray
    slot_pairs: np.ndarray
    pair_kind_own: np.ndarray
    slot_extent: np.ndarray
    pair_margin: np.ndarray
    pair_lever: np.ndarray
    pair_reach: np.ndarray
    pair_lever_own: np.ndarray
    jnt_line: np.ndarray
    slot_lever: np.ndarray
    slot_moved: np.ndarray
    jnt_body: np.ndarray
    jnt_down: np.ndarray

    @property
    def tree(self) -> tuple:
        """The kinematic tree as the kernels take it (static body frames last)."""
        return (self.body_parent, self.body_pos, self.body_rot, self.body_jntadr,
                self.body_jntnum, self.body_flags, self.jnt_type, self.jnt_qposadr,
                self.jnt_pos, self.jnt_axis, self.jnt_axis_code, self.qpos0,
                self.body_xpos, self.body_xmat)

    @property
    def motion(self) -> tuple:
        """What the local (configuration-dependent) speed bound needs: per slot its lever
        arms and the joints that move it, per joint its body and the joints after it."""
        return self.slot_lever, self.slot_moved, self.jnt_body, self.jnt_down

    @property
    def geometry(self) -> tuple:
        """Slots and pairs as the kernels take them."""
        return (self.slot_body, self.slot_static, self.slot_pos, self.slot_rot,
                self.slot_type, self.slot_size, self.slot_radius, self.pair_a, self.pair_b,
                self.pair_margin, self.pair_lever, self.pair_reach, self.pair_kind,
                self.pair_fixed, self.slot_pairs, self.slot_inner, self.slot_inner_size,
                self.pair_contact, self.pair_skewer)


#: The fields of :class:`CompiledScene` that differ between scenes of one model (static
#: geoms' places and sizes): a leading scene axis.
PER_SCENE = ("slot_pos", "slot_rot", "slot_size", "slot_radius", "slot_inner",
             "slot_inner_size", "pair_fixed", "pair_reach", "pair_kind", "pair_lever")


# ------------------------------------------------------------------------------ geometry
#: MuJoCo geom type codes (numba reads them as constants).
_GEOM_PLANE, _GEOM_SPHERE = int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_SPHERE)
_GEOM_CAPSULE, _GEOM_BOX = int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_BOX)
_GEOM_CYLINDER = int(mujoco.mjtGeom.mjGEOM_CYLINDER)
_GEOM_ELLIPSOID = int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)
_GEOM_MESH = int(mujoco.mjtGeom.mjGEOM_MESH)


def container(model: mujoco.MjModel, geom: int) -> tuple[int, np.ndarray, np.ndarray, float]:
    """The container of ``geom``: (type, size (3,), centre offset in the geom frame (3,),
    bounding radius about that centre). The container holds every point of the geom as
    MuJoCo collides it (a mesh as its convex hull)."""
    kind, size, offset, radius = _container(int(model.geom_type[geom]), model.geom_size[geom],
                                            model.geom_aabb[geom])
    return int(kind), np.array(size), np.array(offset), float(radius)


@njit
def _container(geom_type, size, aabb):
    """:func:`container` from the geom's MuJoCo type, ``geom_size`` and ``geom_aabb`` rows:
    (type, size, offset, radius) with size and offset as 3-tuples."""
    s0, s1, s2 = size[0], size[1], size[2]
    zero = (0.0, 0.0, 0.0)
    if geom_type == _GEOM_SPHERE:
        return SPHERE, (s0, s1, s2), zero, s0
    if geom_type == _GEOM_CAPSULE:
        return CAPSULE, (s0, s1, s2), zero, s0 + s1
    if geom_type == _GEOM_BOX:
        return BOX, (s0, s1, s2), zero, math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    if geom_type == _GEOM_CYLINDER:
        return CYLINDER, (s0, s1, s2), zero, math.hypot(s0, s1)
    if geom_type == _GEOM_ELLIPSOID:
        return BOX, (s0, s1, s2), zero, max(s0, max(s1, s2))
    if geom_type == _GEOM_MESH:
        # geom_aabb: the (centre, half-size) box of the mesh's vertices in the geom frame,
        # so it holds their convex hull, which is what MuJoCo collides.
        h0 = aabb[3] * (1.0 + 1e-12) + 1e-12
        h1 = aabb[4] * (1.0 + 1e-12) + 1e-12
        h2 = aabb[5] * (1.0 + 1e-12) + 1e-12
        return BOX, (h0, h1, h2), (aabb[0], aabb[1], aabb[2]), math.sqrt(h0 * h0 + h1 * h1
                                                                        + h2 * h2)
    if geom_type == _GEOM_PLANE:
        return PLANE, (s0, s1, s2), zero, math.inf
    return UNBOUNDED, (s0, s1, s2), zero, math.inf


def inner(model: mujoco.MjModel, geom: int) -> tuple[int, np.ndarray]:
    """The inner shape of ``geom`` (module docstring): (kind, size (3,)) in the frame of its
    container, ``NO_INNER`` for a mesh whose hull is not its bounding box, an unknown kind
    or a plane that moves."""
    box_mesh = False
    if model.geom_type[geom] == _GEOM_MESH:
        box_mesh = _hull_is_box(model, geom)
    kind, size = _inner(int(model.geom_type[geom]), model.geom_size[geom], model.geom_aabb[geom],
                        box_mesh)
    return int(kind), np.array(size)


def _hull_is_box(model: mujoco.MjModel, geom: int) -> bool:
    """The mesh of ``geom`` is the eight corners of its bounding box (``geom_aabb``, in the
    geom frame, computed by MuJoCo from these very vertices): its hull is that box."""
    mesh = model.geom_dataid[geom]
    start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    vertices = model.mesh_vert[start : start + count].astype(np.float64)
    centre, half = model.geom_aabb[geom][:3], model.geom_aabb[geom][3:]
    offsets = vertices - centre
    if count != 8 or not np.all(np.abs(np.abs(offsets) - half) <= 1e-12 * (1.0 + half)):
        return False
    return len({tuple(np.sign(row)) for row in offsets}) == 8


@njit
def _inner(geom_type, size, aabb, box_mesh):
    """:func:`inner` from the geom's MuJoCo type, ``geom_size``, ``geom_aabb`` and whether a
    mesh's hull is its box: (kind, size as a 3-tuple)."""
    s0, s1, s2 = size[0], size[1], size[2]
    if geom_type == _GEOM_SPHERE:
        return SPHERE, (s0, 0.0, 0.0)
    if geom_type == _GEOM_CAPSULE:
        return CAPSULE, (s0, s1, 0.0)
    if geom_type == _GEOM_BOX:
        return BOX, (s0, s1, s2)
    if geom_type == _GEOM_CYLINDER:  # the capsule of its radius, or the square in a disc
        if s1 >= s0:
            return CAPSULE, (s0, s1 - s0, 0.0)
        return BOX, (s0 * _HALF_SQRT2, s0 * _HALF_SQRT2, s1)
    if geom_type == _GEOM_ELLIPSOID:
        return SPHERE, (min(s0, min(s1, s2)), 0.0, 0.0)
    if geom_type == _GEOM_MESH and box_mesh:
        return BOX, (aabb[3], aabb[4], aabb[5])
    if geom_type == _GEOM_PLANE:
        return PLANE, (s0, s1, s2)
    return NO_INNER, (0.0, 0.0, 0.0)


def _quat_to_mat(quat) -> np.ndarray:
    mat = np.empty((3, 3))
    _quat_matrix(np.asarray(quat, dtype=np.float64), mat)
    return mat


@njit
def _quat_matrix(q, out):
    """``out`` (3, 3) = the rotation of unit quaternion ``q`` (w, x, y, z), as
    ``mju_quat2Mat`` computes it."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    if w == 1.0 and x == 0.0 and y == 0.0 and z == 0.0:
        for i in range(3):
            for j in range(3):
                out[i, j] = 1.0 if i == j else 0.0
        return
    ww, wx, wy, wz = w * w, w * x, w * y, w * z
    xx, xy, xz, yy, yz, zz = x * x, x * y, x * z, y * y, y * z, z * z
    # Summed as MuJoCo's build does (found by comparison), so its frames come out the same.
    out[0, 0] = (ww - yy) + (xx - zz)
    out[1, 1] = (ww + yy) - (xx + zz)
    out[2, 2] = (ww - yy) - (xx - zz)
    out[0, 1], out[0, 2] = 2.0 * (xy - wz), 2.0 * (xz + wy)
    out[1, 0], out[1, 2] = 2.0 * (xy + wz), 2.0 * (yz - wx)
    out[2, 0], out[2, 1] = 2.0 * (xz - wy), 2.0 * (yz + wx)


def _ancestors(model: mujoco.MjModel, body: int) -> list[int]:
    chain = []
    while body != 0:
        chain.append(body)
        body = int(model.body_parentid[body])
    return chain


def _body_frame(model: mujoco.MjModel, body: int) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and offset of ``body``'s frame in its parent's (before its joints act)."""
    return _quat_to_mat(model.body_quat[body]), np.array(model.body_pos[body], dtype=float)


def _levers(model: mujoco.MjModel, body: int, centre: np.ndarray, radius: float,
            dof: int) -> np.ndarray:
    """(njnt,) bound on the speed of any point within ``radius`` of ``centre`` (in
    ``body``'s frame) per unit speed of each joint, over all configurations: 1 for a slide,
    0 for joints that do not move the body, and for a hinge the largest distance of such a
    point from the hinge's axis. That distance is the part of the chain held rigidly in
    the hinge's own body (up to the next body with joints), measured perpendicular to the
    axis, plus every length after it (body offsets, slide strokes, anchors off a body's
    origin, the point's radius): the triangle inequality. Joints from ``dof`` on never
    move in checks (they stay at ``qpos0``)."""
    chain = list(reversed(_ancestors(model, body)))  # root-side first, ``body`` last
    levers = np.zeros(model.njnt)
    for index, owner in enumerate(chain):
        first, count = int(model.body_jntadr[owner]), int(model.body_jntnum[owner])
        for j in range(first, first + count):
            if model.jnt_type[j] == _SLIDE:
                levers[j] = 1.0
                continue
            # In the owner's frame: the fixed part reaches from the anchor to the origin
            # of the next jointed body (or to the point itself), the rest is any length.
            rotation, offset = np.eye(3), np.zeros(3)
            rest = 0.0 if j == first + count - 1 else math.inf  # several joints: no bound
            tip = None
            for later in chain[index + 1 :]:
                turn, shift = _body_frame(model, later)
                offset, rotation = offset + rotation @ shift, rotation @ turn
                if model.body_jntnum[later]:
                    tip = offset
                    rest += _reach_after(model, chain[chain.index(later) :], centre, radius,
                                         dof)
                    break
            if tip is None:
                tip = offset + rotation @ centre
                rest += radius
            axis = model.jnt_axis[j] / np.linalg.norm(model.jnt_axis[j])
            arm_vector = tip - model.jnt_pos[j]
            perpendicular = arm_vector - axis * (axis @ arm_vector)
            levers[j] = float(np.linalg.norm(perpendicular)) + rest
    return levers


def _reach_after(model: mujoco.MjModel, bodies: list[int], centre: np.ndarray,
                 radius: float, dof: int) -> float:
    """Bound on the distance of any point within ``radius`` of ``centre`` (in the last
    body's frame) from the origin of ``bodies[0]`` (before its joints act), over all
    configurations of the joints of ``bodies``."""
    reach = float(np.linalg.norm(centre)) + radius
    for b in bodies:
        if b != bodies[0]:
            reach += float(np.linalg.norm(model.body_pos[b]))
        first, count = int(model.body_jntadr[b]), int(model.body_jntnum[b])
        for j in range(first, first + count):
            if j >= dof:
                continue
            if model.jnt_type[j] == _SLIDE:
                if not model.jnt_limited[j]:
                    return math.inf
                adr = model.jnt_qposadr[j]
                reach += float(np.max(np.abs(model.jnt_range[j] - model.qpos0[adr])))
            else:
                reach += 2.0 * float(np.linalg.norm(model.jnt_pos[j]))  # an off-origin hinge
    return reach


def _moved_by(model: mujoco.MjModel, body: int) -> np.ndarray:
    moved = np.zeros(model.njnt, dtype=bool)
    for b in _ancestors(model, body):
        first, count = int(model.body_jntadr[b]), int(model.body_jntnum[b])
        moved[first : first + count] = True
    return moved


#: Collinearity tolerance (m, and sines) of the symmetry test below.
_ON_LINE = 1e-9


def _keeps_line(model: mujoco.MjModel, data: mujoco.MjData, joint: int, point: np.ndarray,
                direction: np.ndarray) -> bool:
    """Whether ``joint`` maps the world line (``point``, unit ``direction``, at ``data``'s
    configuration) to itself: a slide along it, or a hinge about it."""
    axis = data.xaxis[joint]
    if np.linalg.norm(np.cross(axis, direction)) > _ON_LINE:
        return False
    if model.jnt_type[joint] == _SLIDE:
        return True
    return bool(np.linalg.norm(np.cross(data.xanchor[joint] - point, direction)) <= _ON_LINE)


def _line_fixed_between(model: mujoco.MjModel, data: mujoco.MjData, point: np.ndarray,
                        direction: np.ndarray, lower: int, upper: int) -> bool:
    """Whether a line fixed to body ``lower`` stays fixed relative to body ``upper`` (an
    ancestor, or welded to one) in every configuration: every joint on the way up keeps
    it (slides along it, hinges about it)."""
    target, body = int(model.body_weldid[upper]), lower
    while int(model.body_weldid[body]) != target:
        first, count = int(model.body_jntadr[body]), int(model.body_jntnum[body])
        if not all(_keeps_line(model, data, j, point, direction)
                   for j in range(first, first + count)):
            return False
        if body == 0:
            return False
        body = int(model.body_parentid[body])
    return True


def _symmetric_about(model: mujoco.MjModel, data: mujoco.MjData, geom: int,
                     point: np.ndarray, direction: np.ndarray) -> bool:
    """Whether the world line (``point``, ``direction``) is an axis of symmetry of
    ``geom`` at ``data``'s configuration: a sphere's centre on it, or a capsule's or
    cylinder's axis along it (:func:`_symmetric_line`)."""
    # Any other geom type as a box: a kind with no axis of symmetry here.
    kind = {_GEOM_SPHERE: SPHERE, _GEOM_CAPSULE: CAPSULE,
            _GEOM_CYLINDER: CYLINDER}.get(int(model.geom_type[geom]), BOX)
    axis = data.geom_xmat[geom].reshape(3, 3)[:, 2]
    return bool(_symmetric_line(kind, *data.geom_xpos[geom], *axis, *point, *direction))


@njit
def _symmetric_line(kind, cx, cy, cz, nx, ny, nz, px, py, pz, ux, uy, uz):
    """Whether the line through (px, py, pz) along the unit (ux, uy, uz) is an axis of
    symmetry of a shape of container ``kind`` centred at (cx, cy, cz) with axis (a
    plane's normal) (nx, ny, nz): a sphere's centre on it, a capsule's or cylinder's axis
    along it, a plane's normal along it; no other kind. NaN anywhere: not symmetric."""
    # |(c − p) × u|: the centre's distance from the line.
    dx, dy, dz = cx - px, cy - py, cz - pz
    off = math.sqrt((dy * uz - dz * uy) ** 2 + (dz * ux - dx * uz) ** 2
                    + (dx * uy - dy * ux) ** 2)
    # |n × u|: the sine between the shape's axis and the line.
    tilt = math.sqrt((ny * uz - nz * uy) ** 2 + (nz * ux - nx * uz) ** 2
                     + (nx * uy - ny * ux) ** 2)
    if kind == PLANE:
        return tilt <= _ON_LINE
    if kind == SPHERE:
        return off <= _ON_LINE
    if kind == CAPSULE or kind == CYLINDER:
        return off <= _ON_LINE and tilt <= _ON_LINE
    return False


def _spins(model: mujoco.MjModel, data: mujoco.MjData, joint: int, mover: int) -> bool:
    """Whether hinge ``joint``, which moves geom ``mover``, only spins it in place in every
    configuration: its axis line is an axis of symmetry of ``mover`` and fixed to mover's
    body. Such a joint keeps mover's distance to anything it does not move."""
    line = _hinge_line(model, data, joint)
    if line is None:
        return False
    point, direction = line
    return (_symmetric_about(model, data, mover, point, direction)
            and _line_fixed_between(model, data, point, direction,
                                    int(model.geom_bodyid[mover]), int(model.jnt_bodyid[joint])))


def _turns_around(model: mujoco.MjModel, data: mujoco.MjData, joint: int, other: int) -> bool:
    """Whether hinge ``joint``, which does not move geom ``other`` (on a moving body), turns
    what it moves about an axis of symmetry of ``other`` fixed to other's body in every
    configuration: the distances to ``other`` stay. (Static geoms are left to
    :func:`_world_lines` and :func:`_static_levers`: a refresh may move them.)"""
    line = _hinge_line(model, data, joint)
    if line is None or model.body_weldid[model.geom_bodyid[other]] == 0:
        return False
    point, direction = line
    home = int(model.jnt_bodyid[joint])
    return (_symmetric_about(model, data, other, point, direction)
            and _line_fixed_between(model, data, point, direction,
                                    int(model.body_parentid[home]),
                                    int(model.geom_bodyid[other])))


def _hinge_line(model: mujoco.MjModel, data: mujoco.MjData,
                joint: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The world line (a point, the unit direction) of a hinge that is its body's only
    joint, at ``data``'s configuration; None for any other joint."""
    home = int(model.jnt_bodyid[joint])
    if model.jnt_type[joint] == _SLIDE or model.body_jntnum[home] != 1:
        return None
    direction = data.xaxis[joint].copy()
    return data.xanchor[joint].copy(), direction / np.linalg.norm(direction)


def _world_lines(model: mujoco.MjModel, data: mujoco.MjData, dof: int) -> np.ndarray:
    """(njnt, 6): per hinge (its body's only joint, among the first ``dof``) whose axis
    line stays fixed in the world in every configuration, a point of that line and its
    unit direction; NaN rows for every other joint. Such a joint turns what it moves about
    that line: a static geom symmetric about it keeps its distance to all of it."""
    lines = np.full((model.njnt, 6), np.nan)
    for joint in range(min(dof, model.njnt)):
        line = _hinge_line(model, data, joint)
        if line is None:
            continue
        point, direction = line
        if _line_fixed_between(model, data, point, direction,
                               int(model.body_parentid[model.jnt_bodyid[joint]]), 0):
            lines[joint, :3], lines[joint, 3:] = point, direction
    return lines


@njit
def _static_levers(k, b, slot_type, slot_pos, slot_rot, pair_lever_own, jnt_line, pair_lever):
    """Pair ``k``'s lever arms (``pair_lever[:, k]``) against its static slot ``b`` where
    it lies now: its own levers, but 0 for a joint that turns the pair's moving geom about
    a world-fixed line (``jnt_line``) that is an axis of symmetry of ``b`` — a sphere's
    centre on it, a capsule's or cylinder's axis along it, a plane's normal along it."""
    cx, cy, cz = slot_pos[b, 0], slot_pos[b, 1], slot_pos[b, 2]
    nx, ny, nz = slot_rot[b, 0, 2], slot_rot[b, 1, 2], slot_rot[b, 2, 2]
    for j in range(pair_lever_own.shape[0]):
        lever = pair_lever_own[j, k]
        if lever > 0.0 and _symmetric_line(slot_type[b], cx, cy, cz, nx, ny, nz,
                                           jnt_line[j, 0], jnt_line[j, 1], jnt_line[j, 2],
                                           jnt_line[j, 3], jnt_line[j, 4], jnt_line[j, 5]):
            lever = 0.0
        pair_lever[j, k] = lever


def _joints_after(model: mujoco.MjModel) -> np.ndarray:
    """(njnt, njnt) bool: joint i acts after joint j on the way out to the tips (a later
    joint of j's body, or a joint of a body below it): what moves points relative to j's
    axis."""
    after = np.zeros((model.njnt, model.njnt), dtype=bool)
    for i in range(model.njnt):
        body = int(model.jnt_bodyid[i])
        for j in range(model.njnt):
            owner = int(model.jnt_bodyid[j])
            after[j, i] = (owner == body and i > j) or (
                owner != body and owner in _ancestors(model, body))
    return after


def _own_levers(model: mujoco.MjModel, data: mujoco.MjData, geoms: np.ndarray,
                pair_a: np.ndarray, pair_b: np.ndarray, slot_static: np.ndarray,
                levers: np.ndarray, moved: np.ndarray, dof: int) -> np.ndarray:
    """(njnt, P) every pair's lever arms per joint (a path's rates in one contiguous pass
    per joint), but for the symmetries of static partners (a scene's: ``_static_levers``):
    against a static partner, the moving geom's own; between two moving geoms, those of
    the joints that move one and not the other (the joints that move both turn the pair
    rigidly together). A joint drops out that spins a geom about an axis of symmetry of
    its own, or turns it about one of the other's (moving) geom, fixed to that geom's body
    in every configuration."""
    # Both tests depend on one joint and one geom only, and a moving geom meets many
    # partners (every obstacle slot): each (joint, geom) is decided once.
    spins: dict[tuple[int, int], bool] = {}
    turns: dict[tuple[int, int], bool] = {}
    lever_own = np.zeros((len(pair_a), model.njnt))
    for k, (a, b) in enumerate(zip(pair_a, pair_b, strict=True)):
        if slot_static[b]:
            lever_own[k], only_a = levers[a], moved[a]
        else:
            only_a, only_b = moved[a] & ~moved[b], moved[b] & ~moved[a]
            lever_own[k] = np.where(only_a, levers[a], 0.0) + np.where(only_b, levers[b], 0.0)
        for joint in np.flatnonzero(lever_own[k]).tolist():
            mover, other = (a, b) if only_a[joint] else (b, a)
            spin = (joint, int(geoms[mover]))
            if spin not in spins:
                spins[spin] = _spins(model, data, *spin)
            if spins[spin]:
                lever_own[k, joint] = 0.0
                continue
            turn = (joint, int(geoms[other]))
            if turn not in turns:
                turns[turn] = _turns_around(model, data, *turn)
            if turns[turn]:
                lever_own[k, joint] = 0.0
    lever_own[:, dof:] = 0.0
    return np.ascontiguousarray(lever_own.T)


def compile_scene(model: mujoco.MjModel, dof: int, pairs: np.ndarray) -> CompiledScene:
    """The flat arrays of ``model`` (margins as set on it) for the geom ``pairs`` (P, 2)
    that ``mj_collision`` may test. ``ValueError`` for what the filter cannot bound
    (joints other than hinges and slides, explicit contact pairs, mocap bodies, margin
    overrides)."""
    _check_supported(model)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    static_body = model.body_weldid == 0

    geoms = np.unique(pairs) if len(pairs) else np.zeros(0, dtype=np.int64)
    slot_of = {int(g): s for s, g in enumerate(geoms)}
    n_slots = len(geoms)
    slot_body = model.geom_bodyid[geoms].astype(np.int64)
    slot_static = static_body[slot_body]
    slot_pos, slot_rot = np.zeros((n_slots, 3)), np.zeros((n_slots, 3, 3))
    slot_type = np.zeros(n_slots, dtype=np.int64)
    slot_size, slot_radius = np.zeros((n_slots, 3)), np.zeros(n_slots)
    slot_inner, inner_size = np.full(n_slots, NO_INNER, dtype=np.int64), np.zeros((n_slots, 3))
    levers, moved = np.zeros((n_slots, model.njnt)), np.zeros((n_slots, model.njnt), dtype=bool)
    extent = np.full(n_slots, np.inf)  # moving slots: farthest reach from the world origin
    for s, g in enumerate(geoms):
        kind, size, offset, radius = container(model, int(g))
        slot_type[s], slot_size[s], slot_radius[s] = kind, size, radius
        slot_inner[s], inner_size[s] = inner(model, int(g))
        if slot_static[s]:  # fixed in the world: its frame once, from MuJoCo
            rot = data.geom_xmat[g].reshape(3, 3).copy()
            slot_rot[s], slot_pos[s] = rot, data.geom_xpos[g] + rot @ offset
            continue
        if kind in (PLANE, UNBOUNDED):
            slot_type[s] = UNBOUNDED  # a moving plane: left to MuJoCo at every sample
            slot_inner[s] = NO_INNER
        rot = _quat_to_mat(model.geom_quat[g])
        slot_rot[s], slot_pos[s] = rot, model.geom_pos[g] + rot @ offset
        levers[s] = _levers(model, int(slot_body[s]), slot_pos[s],
                            radius if np.isfinite(radius) else 0.0, dof)
        moved[s] = _moved_by(model, int(slot_body[s]))
        chain = list(reversed(_ancestors(model, int(slot_body[s]))))
        extent[s] = float(np.linalg.norm(model.body_pos[chain[0]])) + _reach_after(
            model, chain, slot_pos[s], radius if np.isfinite(radius) else 0.0, dof)

    # Pairs grouped by their moving slot a (the kernel loads a's frame once per group), a
    # static solid partner first, then a plane, then a moving one: (a, kind) order.
    ends = [(slot_of[int(g1)], slot_of[int(g2)]) for g1, g2 in pairs.tolist()]
    ends = [(b, a) if slot_static[a] else (a, b) for a, b in ends]
    kinds = [2 if not slot_static[b] else (1 if slot_type[b] == PLANE else 0) for _, b in ends]
    order = sorted(range(len(ends)), key=lambda k: (ends[k][0], kinds[k]))
    pair_a = np.array([ends[k][0] for k in order], dtype=np.int64)
    pair_b = np.array([ends[k][1] for k in order], dtype=np.int64)
    pair_kind = np.array([kinds[k] for k in order], dtype=np.int64)
    margin = (model.geom_margin[pairs].sum(axis=1)[order] if len(pairs) else np.zeros(0))
    pair_fixed = np.zeros((len(pair_a), 6))  # a static partner's centre (and plane normal)
    for k in np.flatnonzero(slot_static[pair_b]).tolist():
        pair_fixed[k, :3], pair_fixed[k, 3:] = slot_pos[pair_b[k]], slot_rot[pair_b[k]][:, 2]
    pair_lever_own = _own_levers(model, data, geoms, pair_a, pair_b, slot_static, levers,
                                 moved, dof)
    jnt_line = _world_lines(model, data, dof)
    pair_lever = pair_lever_own.copy()
    for k in np.flatnonzero(slot_static[pair_b]).tolist():
        _static_levers(k, int(pair_b[k]), slot_type, slot_pos, slot_rot, pair_lever_own,
                       jnt_line, pair_lever)
    pair_contact = np.where(_witnessed(model, geoms, pair_a, pair_b, slot_inner),
                            margin - WITNESS_TOLERANCE, -math.inf)
    slot_pairs = np.searchsorted(pair_a, np.arange(n_slots + 1)).astype(np.int64)
    body_rot = np.array([_quat_to_mat(q) for q in model.body_quat])
    body_flags = np.where(static_body, 1, 0) | np.where(
        np.all(body_rot == np.eye(3), axis=(1, 2)), 2, 0)
    axis_code = np.full(model.njnt, 6, dtype=np.int64)
    for j, axis in enumerate(model.jnt_axis):
        for code, unit in enumerate(np.vstack([np.eye(3), -np.eye(3)])):
            if np.array_equal(axis, unit):
                axis_code[j] = code
    scene = dict(
        body_parent=model.body_parentid.astype(np.int64),
        body_pos=np.array(model.body_pos, dtype=np.float64),
        body_rot=body_rot,
        body_jntadr=model.body_jntadr.astype(np.int64),
        body_jntnum=model.body_jntnum.astype(np.int64),
        body_flags=body_flags.astype(np.int64),
        jnt_type=model.jnt_type.astype(np.int64),
        jnt_qposadr=model.jnt_qposadr.astype(np.int64),
        jnt_pos=np.array(model.jnt_pos, dtype=np.float64),
        jnt_axis=np.array(model.jnt_axis, dtype=np.float64),
        jnt_axis_code=axis_code,
        qpos0=np.array(model.qpos0, dtype=np.float64),
        body_xpos=np.where(static_body[:, None], data.xpos, 0.0),
        body_xmat=np.where(static_body[:, None, None], data.xmat.reshape(-1, 3, 3), 0.0),
        slot_geom=geoms.astype(np.int64),
        slot_body=slot_body,
        slot_static=slot_static,
        slot_pos=slot_pos,
        slot_rot=slot_rot,
        slot_type=slot_type,
        slot_size=slot_size,
        slot_radius=slot_radius,
        pair_a=pair_a,
        pair_b=pair_b,
        pair_kind=pair_kind,
        pair_fixed=pair_fixed,
        slot_pairs=slot_pairs,
        pair_kind_own=pair_kind.copy(),
        slot_extent=extent,
        pair_margin=margin + DISTANCE_TOLERANCE,
        pair_lever=pair_lever,
        pair_lever_own=pair_lever_own,
        jnt_line=jnt_line,
        # Bounding radii plus margin: a plane (always ``b``) adds no radius. Summed as
        # ``refresh_static`` sums them, so a refresh rewrites the same bits.
        pair_reach=(slot_radius[pair_a] + np.where(slot_type[pair_b] == PLANE, 0.0,
                                                   slot_radius[pair_b])
                    + (margin + DISTANCE_TOLERANCE)),
        slot_lever=np.where(np.arange(model.njnt) < dof, levers, 0.0),
        slot_moved=moved & (np.arange(model.njnt) < dof),
        jnt_body=model.jnt_bodyid.astype(np.int64),
        jnt_down=_joints_after(model),
        slot_inner=slot_inner,
        slot_inner_size=inner_size,
        pair_contact=pair_contact,
        pair_skewer=_capsule_box(model, geoms, pair_a, pair_b),
    )
    for name in PER_SCENE:  # one scene
        scene[name] = np.ascontiguousarray(scene[name][None])
    return CompiledScene(**scene)


def _capsule_box(model: mujoco.MjModel, geoms: np.ndarray, pair_a: np.ndarray,
                 pair_b: np.ndarray) -> np.ndarray:
    """(P,) bool: the pair is a primitive capsule and a primitive box (MuJoCo's capsule–box
    collider, which misses a capsule skewering the box)."""
    kind = model.geom_type[geoms]
    a, b = kind[pair_a], kind[pair_b]
    return ((a == _GEOM_CAPSULE) & (b == _GEOM_BOX)) | ((a == _GEOM_BOX) & (b == _GEOM_CAPSULE))


def _check_supported(model: mujoco.MjModel) -> None:
    """``ValueError`` for what the filter cannot bound (see :func:`compile_scene`)."""
    if not np.isin(model.jnt_type, (_SLIDE, _HINGE)).all() or model.nq != model.njnt:
        raise ValueError("the compiled filter supports hinge and slide joints only")
    if model.npair or model.nmocap:
        raise ValueError("the compiled filter supports no explicit contact pairs or mocap bodies")
    if model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_OVERRIDE:
        raise ValueError("the compiled filter needs per-geom margins (no contact override)")


def _witnessed(model: mujoco.MjModel, geoms: np.ndarray, pair_a: np.ndarray,
               pair_b: np.ndarray, slot_inner: np.ndarray) -> np.ndarray:
    """(P,) bool: a pair that a witness may prove in contact (its inner shapes, or one's
    inner sphere or capsule against the other's cylinder): both have an inner shape, their
    collider reports every contact inside the margin (not two primitive boxes:
    google-deepmind/mujoco#2471, docs/models.md), contacts are enabled at all, and the
    convex collider runs at least MuJoCo's default iterations and tolerance (the settings
    the witnesses were studied with: with fewer iterations it misses contacts they prove)."""
    off = mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    if (model.opt.disableflags & off or model.opt.ccd_iterations < CCD_ITERATIONS
            or model.opt.ccd_tolerance > CCD_TOLERANCE):
        return np.zeros(len(pair_a), dtype=bool)
    kind = model.geom_type[geoms]
    boxes = (kind[pair_a] == _GEOM_BOX) & (kind[pair_b] == _GEOM_BOX)
    return (slot_inner[pair_a] != NO_INNER) & (slot_inner[pair_b] != NO_INNER) & ~boxes


def refresh_static(scene: CompiledScene, model: mujoco.MjModel,
                   geoms: np.ndarray | None = None) -> None:
    """Re-read static geoms of ``scene`` (its one scene) from ``model`` after their sizes
    or places changed (the per-episode clutter): their world frames, containers, inner
    shapes and bounding radii, and what the pairs keep of them. ``geoms``: the geom ids
    that changed (default every static one). The tree, the candidate pairs and every
    moving geom are unchanged, so nothing else is recomputed."""
    if len(scene.slot_pos) != 1:
        raise ValueError("refresh_static refreshes the scene of one filter (a stack's row)")
    every = geoms is None
    geoms = np.zeros(0, dtype=np.int64) if every else np.asarray(geoms, dtype=np.int64)
    changed = _refresh_static(
        every, geoms, scene.slot_geom, scene.slot_body, scene.slot_static, scene.slot_type,
        scene.slot_size[0], scene.slot_radius[0], scene.slot_pos[0], scene.slot_rot[0],
        scene.slot_inner[0], scene.slot_inner_size[0], scene.body_xpos, scene.body_xmat,
        scene.pair_a, scene.pair_b, scene.pair_margin, scene.pair_kind_own, scene.slot_extent,
        scene.pair_fixed[0], scene.pair_reach[0], scene.pair_kind[0], scene.pair_lever_own,
        scene.jnt_line, scene.pair_lever[0], model.geom_type, model.geom_size, model.geom_aabb,
        model.geom_quat, model.geom_pos)
    if changed >= 0:
        name = model.geom(int(scene.slot_geom[changed])).name
        raise ValueError(f"geom {name!r} changed its kind")


@njit
def _refresh_static(every, geoms, slot_geom, slot_body, slot_static, slot_type, slot_size,
                    slot_radius, slot_pos, slot_rot, slot_inner, slot_inner_size, body_xpos,
                    body_xmat, pair_a, pair_b, pair_margin, pair_kind_own, slot_extent,
                    pair_fixed, pair_reach, pair_kind, pair_lever_own, jnt_line, pair_lever,
                    geom_type, geom_size, geom_aabb, geom_quat, geom_pos):
    """:func:`refresh_static` on the arrays: returns −1, or the slot whose geom changed
    its container kind (left half-refreshed: the caller raises)."""
    refreshed = np.zeros(len(slot_geom), dtype=np.bool_)
    own = np.empty((3, 3))
    for s in range(len(slot_geom)):
        if not slot_static[s]:
            continue
        g = slot_geom[s]
        if not (every or _listed(geoms, g)):
            continue
        kind, size, offset, radius = _container(geom_type[g], geom_size[g], geom_aabb[g])
        if kind != slot_type[s]:
            return s
        refreshed[s] = True
        # A mesh keeps its vertices, so whether its hull is its box does not change.
        box_mesh = geom_type[g] == _GEOM_MESH and slot_inner[s] == BOX
        inner_kind, inner_size = _inner(geom_type[g], geom_size[g], geom_aabb[g], box_mesh)
        slot_inner[s] = inner_kind
        # A static geom's frame: its (static) body's, known since construction, times its own.
        body = slot_body[s]
        _quat_matrix(geom_quat[g], own)
        for i in range(3):
            slot_size[s, i] = size[i]
            slot_inner_size[s, i] = inner_size[i]
            for j in range(3):
                slot_rot[s, i, j] = (body_xmat[body, i, 0] * own[0, j]
                                     + body_xmat[body, i, 1] * own[1, j]
                                     + body_xmat[body, i, 2] * own[2, j])
        slot_radius[s] = radius
        for i in range(3):
            slot_pos[s, i] = (body_xpos[body, i]
                              + (body_xmat[body, i, 0] * geom_pos[g, 0]
                                 + body_xmat[body, i, 1] * geom_pos[g, 1]
                                 + body_xmat[body, i, 2] * geom_pos[g, 2])
                              + (slot_rot[s, i, 0] * offset[0] + slot_rot[s, i, 1] * offset[1]
                                 + slot_rot[s, i, 2] * offset[2]))
    _refresh_pairs(refreshed, slot_pos, slot_rot, slot_type, slot_radius, pair_a, pair_b,
                   pair_margin, pair_kind_own, slot_extent, pair_fixed, pair_reach, pair_kind,
                   pair_lever_own, jnt_line, pair_lever)
    return -1


@njit
def _listed(geoms, g):
    for i in range(len(geoms)):
        if geoms[i] == g:
            return True
    return False


@njit
def _refresh_pairs(refreshed, slot_pos, slot_rot, slot_type, slot_radius, pair_a, pair_b,
                   pair_margin, pair_kind_own, slot_extent, pair_fixed, pair_reach, pair_kind,
                   pair_lever_own, jnt_line, pair_lever):
    """What the pairs keep of their ``refreshed`` static slots (see :func:`refresh_static`)."""
    for k in range(len(pair_b)):
        b = pair_b[k]
        if not refreshed[b]:
            continue
        x, y, z = slot_pos[b, 0], slot_pos[b, 1], slot_pos[b, 2]
        pair_fixed[k, 0], pair_fixed[k, 1], pair_fixed[k, 2] = x, y, z
        pair_fixed[k, 3], pair_fixed[k, 4], pair_fixed[k, 5] = (slot_rot[b, 0, 2],
                                                                slot_rot[b, 1, 2],
                                                                slot_rot[b, 2, 2])
        # Bounding radii plus margin: a plane adds no radius.
        partner = 0.0 if slot_type[b] == PLANE else slot_radius[b]
        pair_reach[k] = slot_radius[pair_a[k]] + partner + pair_margin[k]
        # A static geom beyond everything a's points can ever reach (a parked obstacle
        # slot) cannot come within the margin: its pairs are skipped (kind 3) until it
        # moves back.
        gap = math.sqrt(x * x + y * y + z * z) - partner - pair_margin[k]
        far = pair_kind_own[k] == 0 and gap > slot_extent[pair_a[k]]
        pair_kind[k] = OUT_OF_REACH if far else pair_kind_own[k]
        _static_levers(k, b, slot_type, slot_pos, slot_rot, pair_lever_own, jnt_line,
                       pair_lever)

