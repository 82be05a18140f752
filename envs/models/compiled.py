"""The compiled collision filter: bounds that prove samples free, MuJoCo for the rest.

:class:`~envs.models.collision.CollisionChecker`'s ``"compiled"`` backend. It answers the
same questions as the exact backends (does configuration q touch anything closer than δ;
which grid sample of a linear path is the first to), with the same answers, but decides
most samples without MuJoCo:

1. **Geometry as flat arrays, read from the compiled model** (:class:`CompiledScene`): the
   kinematic tree (hinge and slide joints, body offsets), every collision geom that
   ``mj_collision`` may test (:func:`~envs.models.collision.candidate_pairs`) as a
   *container* shape that holds it (spheres, capsules and boxes as themselves, a convex
   mesh as its bounding box, a cylinder as both the capsule and the box around it, an
   ellipsoid as its box, a plane as its half-space), each inside a bounding sphere, and per
   pair the lever arms that bound how fast its distance can change (per geom, over all
   configurations; ``docs/models.md``). No per-arm code: every model ``envs.models``
   builds gets it.
2. **Lower bounds in the kernel**: forward kinematics of the tree, then per candidate
   pair first the bounding spheres' gap and, only where that could matter, an exact
   distance between the containers (sphere/capsule/box/half-space pairs in closed form,
   box–box by separating axes, which never overestimates). A container holds its geom,
   so these never exceed the true distance.
3. **Proof or hand-over**: a sample at which every pair is provably farther than its
   contact margin (δ, plus ``DISTANCE_TOLERANCE``) is free, exactly as ``mj_collision``
   would find it. Any other sample goes to ``mj_kinematics`` + ``mj_collision`` on the
   checker's ``MjData``, called from the kernel (:mod:`envs.models.native`): the exact
   check of the Python backends, so every verdict and every first colliding sample is
   theirs.
4. **Paths, coarse to fine**: a path's grid samples (t_i = i/n, as in the module docstring
   of :mod:`~envs.models.collision`) are visited in raked order (the middle of every
   unresolved interval, breadth first), and a free sample's bounds prove its neighbours
   on both sides free (conservative advancement: a pair at distance d approaching at rate
   ≤ L stays farther than the margin for |t − t_i| < (d − margin)/L). A verdict-only call
   stops at the first contact found; a first-sample call keeps resolving the samples
   before it.

All kernels are ``numba.njit(cache=True)``: compiled once per machine into
``__pycache__`` (``warm_up`` does it ahead), loaded in well under a second afterwards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from numba import njit

from . import native

#: Reported distances are trusted only up to this (m): a pair counts as proven free only
#: when its lower bound exceeds the contact margin by this much.
DISTANCE_TOLERANCE = 1e-6

#: A pair (kind) whose static partner lies beyond the moving geom's reach: skipped.
OUT_OF_REACH = 3
#: Container shapes (codes shared with the kernels).
SPHERE, CAPSULE, BOX, CYLINDER, PLANE, UNBOUNDED = 0, 1, 2, 3, 4, 5
#: Joint type codes, MuJoCo's own.
_SLIDE, _HINGE = int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE)


@dataclass(frozen=True, eq=False)
class CompiledScene:
    """Everything the kernels read, as flat arrays (see the module docstring).

    Tree: ``body_*`` (nbody), ``jnt_*`` (njnt), ``qpos0``. Geoms ("slots": only those of
    candidate pairs): body, shape frame in the body frame (for static slots: in the world,
    fixed), container type, size, bounding radius about the shape centre. Pairs: the two
    slots (a static one always second), the contact margin, and per joint the lever arm
    that bounds the rate of change of the pair's distance (m per rad, 1 for a slide).
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
                self.pair_fixed, self.slot_pairs)


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


@njit(cache=True)
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


def _quat_to_mat(quat) -> np.ndarray:
    mat = np.empty((3, 3))
    _quat_matrix(np.asarray(quat, dtype=np.float64), mat)
    return mat


@njit(cache=True)
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


def compile_scene(model: mujoco.MjModel, dof: int, pairs: np.ndarray) -> CompiledScene:
    """The flat arrays of ``model`` (margins as set on it) for the geom ``pairs`` (P, 2)
    that ``mj_collision`` may test. ``ValueError`` for what the filter cannot bound
    (joints other than hinges and slides, explicit contact pairs, mocap bodies, margin
    overrides)."""
    if not np.isin(model.jnt_type, (_SLIDE, _HINGE)).all() or model.nq != model.njnt:
        raise ValueError("the compiled filter supports hinge and slide joints only")
    if model.npair or model.nmocap:
        raise ValueError("the compiled filter supports no explicit contact pairs or mocap bodies")
    if model.opt.enableflags & mujoco.mjtEnableBit.mjENBL_OVERRIDE:
        raise ValueError("the compiled filter needs per-geom margins (no contact override)")
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
    levers, moved = np.zeros((n_slots, model.njnt)), np.zeros((n_slots, model.njnt), dtype=bool)
    extent = np.full(n_slots, np.inf)  # moving slots: farthest reach from the world origin
    for s, g in enumerate(geoms):
        kind, size, offset, radius = container(model, int(g))
        slot_type[s], slot_size[s], slot_radius[s] = kind, size, radius
        if slot_static[s]:  # fixed in the world: its frame once, from MuJoCo
            rot = data.geom_xmat[g].reshape(3, 3).copy()
            slot_rot[s], slot_pos[s] = rot, data.geom_xpos[g] + rot @ offset
            continue
        if kind in (PLANE, UNBOUNDED):
            slot_type[s] = UNBOUNDED  # a moving plane: left to MuJoCo at every sample
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
    pair_lever = np.zeros((len(pair_a), model.njnt))
    pair_fixed = np.zeros((len(pair_a), 6))  # a static partner's centre (and plane normal)
    for k, (a, b) in enumerate(zip(pair_a, pair_b, strict=True)):
        if slot_static[b]:
            pair_lever[k] = levers[a]
            pair_fixed[k, :3], pair_fixed[k, 3:] = slot_pos[b], slot_rot[b][:, 2]
        else:  # joints that move both turn the pair rigidly together and drop out
            only_a, only_b = moved[a] & ~moved[b], moved[b] & ~moved[a]
            pair_lever[k] = np.where(only_a, levers[a], 0.0) + np.where(only_b, levers[b], 0.0)
    pair_lever[:, dof:] = 0.0
    slot_pairs = np.searchsorted(pair_a, np.arange(n_slots + 1)).astype(np.int64)
    body_rot = np.array([_quat_to_mat(q) for q in model.body_quat])
    body_flags = np.where(static_body, 1, 0) | np.where(
        np.all(body_rot == np.eye(3), axis=(1, 2)), 2, 0)
    axis_code = np.full(model.njnt, 6, dtype=np.int64)
    for j, axis in enumerate(model.jnt_axis):
        for code, unit in enumerate(np.vstack([np.eye(3), -np.eye(3)])):
            if np.array_equal(axis, unit):
                axis_code[j] = code
    return CompiledScene(
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
        # Bounding radii plus margin: a plane (always ``b``) adds no radius.
        pair_reach=(slot_radius[pair_a] + np.where(slot_type[pair_b] == PLANE, 0.0,
                                                   slot_radius[pair_b])
                    + margin + DISTANCE_TOLERANCE),
        slot_lever=np.where(np.arange(model.njnt) < dof, levers, 0.0),
        slot_moved=moved & (np.arange(model.njnt) < dof),
        jnt_body=model.jnt_bodyid.astype(np.int64),
        jnt_down=_joints_after(model),
    )


def refresh_static(scene: CompiledScene, model: mujoco.MjModel,
                   geoms: np.ndarray | None = None) -> None:
    """Re-read static geoms of ``scene`` from ``model`` after their sizes or places
    changed (the per-episode clutter): their world frames, containers and bounding radii,
    and what the pairs keep of them. ``geoms``: the geom ids that changed (default every
    static one). The tree, the candidate pairs and every moving geom are unchanged, so
    nothing else is recomputed."""
    every = geoms is None
    geoms = np.zeros(0, dtype=np.int64) if every else np.asarray(geoms, dtype=np.int64)
    changed = _refresh_static(
        every, geoms, scene.slot_geom, scene.slot_body, scene.slot_static, scene.slot_type,
        scene.slot_size, scene.slot_radius, scene.slot_pos, scene.slot_rot, scene.body_xpos,
        scene.body_xmat, scene.pair_a, scene.pair_b, scene.pair_margin, scene.pair_kind_own,
        scene.slot_extent, scene.pair_fixed, scene.pair_reach, scene.pair_kind,
        model.geom_type, model.geom_size, model.geom_aabb, model.geom_quat, model.geom_pos)
    if changed >= 0:
        name = model.geom(int(scene.slot_geom[changed])).name
        raise ValueError(f"geom {name!r} changed its kind")


@njit(cache=True)
def _refresh_static(every, geoms, slot_geom, slot_body, slot_static, slot_type, slot_size,
                    slot_radius, slot_pos, slot_rot, body_xpos, body_xmat, pair_a, pair_b,
                    pair_margin, pair_kind_own, slot_extent, pair_fixed, pair_reach, pair_kind,
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
        # A static geom's frame: its (static) body's, known since construction, times its own.
        body = slot_body[s]
        _quat_matrix(geom_quat[g], own)
        for i in range(3):
            slot_size[s, i] = size[i]
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
                   pair_margin, pair_kind_own, slot_extent, pair_fixed, pair_reach, pair_kind)
    return -1


@njit(cache=True)
def _listed(geoms, g):
    for i in range(len(geoms)):
        if geoms[i] == g:
            return True
    return False


@njit(cache=True)
def _refresh_pairs(refreshed, slot_pos, slot_rot, slot_type, slot_radius, pair_a, pair_b,
                   pair_margin, pair_kind_own, slot_extent, pair_fixed, pair_reach, pair_kind):
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


# -------------------------------------------------------------------- distance kernels
@njit(cache=True, inline="always")
def _clamp(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


@njit(cache=True)
def _point_segment_sq(px, py, pz, ax, ay, az, bx, by, bz):
    dx, dy, dz = bx - ax, by - ay, bz - az
    length = dx * dx + dy * dy + dz * dz
    t = 0.0
    if length > 0.0:
        t = _clamp(((px - ax) * dx + (py - ay) * dy + (pz - az) * dz) / length, 0.0, 1.0)
    ex, ey, ez = ax + t * dx - px, ay + t * dy - py, az + t * dz - pz
    return ex * ex + ey * ey + ez * ez


@njit(cache=True)
def _segment_segment_sq(p1x, p1y, p1z, q1x, q1y, q1z, p2x, p2y, p2z, q2x, q2y, q2z):
    """Squared distance of two segments (Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1x, d1y, d1z = q1x - p1x, q1y - p1y, q1z - p1z
    d2x, d2y, d2z = q2x - p2x, q2y - p2y, q2z - p2z
    rx, ry, rz = p1x - p2x, p1y - p2y, p1z - p2z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-18
    if a <= eps and e <= eps:
        return rx * rx + ry * ry + rz * rz
    if a <= eps:
        s, t = 0.0, _clamp(f / e, 0.0, 1.0)
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= eps:
            t, s = 0.0, _clamp(-c / a, 0.0, 1.0)
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            denom = a * e - b * b
            s = _clamp((b * f - c * e) / denom, 0.0, 1.0) if denom > eps * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t, s = 0.0, _clamp(-c / a, 0.0, 1.0)
            elif t > 1.0:
                t, s = 1.0, _clamp((b - c) / a, 0.0, 1.0)
    ex = p1x + d1x * s - (p2x + d2x * t)
    ey = p1y + d1y * s - (p2y + d2y * t)
    ez = p1z + d1z * s - (p2z + d2z * t)
    return ex * ex + ey * ey + ez * ez


@njit(cache=True)
def _to_box(px, py, pz, c, r):
    """World point -> box frame (``c`` centre, ``r`` rotation as a row-major 9-tuple,
    world = r @ local)."""
    dx, dy, dz = px - c[0], py - c[1], pz - c[2]
    return (r[0] * dx + r[3] * dy + r[6] * dz,
            r[1] * dx + r[4] * dy + r[7] * dz,
            r[2] * dx + r[5] * dy + r[8] * dz)


@njit(cache=True)
def _point_box(px, py, pz, c, r, h0, h1, h2):
    """Distance from a world point to a solid box of half-sizes h (0 inside)."""
    x, y, z = _to_box(px, py, pz, c, r)
    ex = max(abs(x) - h0, 0.0)
    ey = max(abs(y) - h1, 0.0)
    ez = max(abs(z) - h2, 0.0)
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit(cache=True)
def _piece_minimum(lo, hi, s0, s1, s2, d0, d1, d2, h0, h1, h2):
    """Least squared box distance of p(t) = s + t·d over [lo, hi], a piece on which no
    coordinate crosses a face plane: a quadratic qa t² + qb t + qc, minimised exactly."""
    mid = 0.5 * (lo + hi)
    qa = qb = qc = 0.0
    for k in range(3):
        if k == 0:
            s, d, h = s0, d0, h0
        elif k == 1:
            s, d, h = s1, d1, h1
        else:
            s, d, h = s2, d2, h2
        x = s + mid * d
        if x > h:
            offset = s - h
        elif x < -h:
            offset = s + h
        else:
            continue
        qa += d * d
        qb += 2.0 * d * offset
        qc += offset * offset
    if qa > 0.0:
        t = _clamp(-qb / (2.0 * qa), lo, hi)
    else:
        t = lo if qb > 0.0 else hi
    return (qa * t + qb) * t + qc


@njit(cache=True, inline="always")
def _box_axis(axis, s0, s1, s2, d0, d1, d2, h0, h1, h2):
    """(start, direction, half-size) of the segment and the box along box axis ``axis``."""
    if axis == 0:
        return s0, d0, h0
    if axis == 1:
        return s1, d1, h1
    return s2, d2, h2


@njit(cache=True, inline="always")
def _face_crossing(side, s, d, h):
    """(crosses, t): whether the segment s + t·d, 0 < t < 1, crosses the face plane at
    ``side``·h (``side`` ±1) strictly inside, and where; a parallel segment never does."""
    if d == 0.0:
        return False, 0.0
    t = (side * h - s) / d
    if not 0.0 < t < 1.0:
        return False, t
    return True, t


@njit(cache=True, inline="always")
def _insert_sorted(t, c0, c1, c2, c3, c4, c5):
    """The sorted six-tuple c0 ≤ … ≤ c5 with ``t`` inserted in place of its largest entry
    (unused slots hold 2.0, above every breakpoint): one bubble pass, no allocation."""
    if t < c5:
        c5 = t
    if c5 < c4:
        c4, c5 = c5, c4
    if c4 < c3:
        c3, c4 = c4, c3
    if c3 < c2:
        c2, c3 = c3, c2
    if c2 < c1:
        c1, c2 = c2, c1
    if c1 < c0:
        c0, c1 = c1, c0
    return c0, c1, c2, c3, c4, c5


@njit(cache=True, inline="always")
def _piece_end(piece, count, c0, c1, c2, c3, c4, c5):
    """Where piece ``piece`` of the segment ends: breakpoint ``piece`` of the sorted
    c0..c5, or t = 1 for the last piece (``piece`` == ``count``)."""
    if piece >= count:
        return 1.0
    if piece == 0:
        return c0
    if piece == 1:
        return c1
    if piece == 2:
        return c2
    if piece == 3:
        return c3
    if piece == 4:
        return c4
    return c5


@njit(cache=True)
def _segment_box(ax, ay, az, bx, by, bz, c, r, h0, h1, h2):
    """Exact distance from the segment a–b to a solid box: the squared distance along the
    segment is a sum of clamped quadratics, smooth between the breakpoints where a
    coordinate crosses a face plane; each piece is minimised in closed form."""
    s0, s1, s2 = _to_box(ax, ay, az, c, r)
    e0, e1, e2 = _to_box(bx, by, bz, c, r)
    d0, d1, d2 = e0 - s0, e1 - s1, e2 - s2
    # The ≤ 6 interior breakpoints, kept sorted by insertion (no allocation).
    c0 = c1 = c2 = c3 = c4 = c5 = 2.0
    count = 0
    for k in range(6):
        axis, side = k // 2, -1.0 if k % 2 == 0 else 1.0
        s, d, h = _box_axis(axis, s0, s1, s2, d0, d1, d2, h0, h1, h2)
        crosses, t = _face_crossing(side, s, d, h)
        if not crosses:
            continue
        c0, c1, c2, c3, c4, c5 = _insert_sorted(t, c0, c1, c2, c3, c4, c5)
        count += 1
    best = math.inf
    lo = 0.0
    for piece in range(count + 1):
        hi = _piece_end(piece, count, c0, c1, c2, c3, c4, c5)
        value = _piece_minimum(lo, hi, s0, s1, s2, d0, d1, d2, h0, h1, h2)
        if value < best:
            best = value
        lo = hi
    return math.sqrt(max(best, 0.0))


@njit(cache=True)
def _box_box(c1, r1, a0, a1, a2, c2, r2, b0, b1, b2):
    """A lower bound on the distance of two boxes: the largest gap of their projections on
    the 15 separating-axis candidates (face normals and edge cross products); a
    projection never lengthens a distance."""
    dx, dy, dz = c2[0] - c1[0], c2[1] - c1[1], c2[2] - c1[2]
    best = -math.inf
    for k in range(15):
        if k < 3:
            lx, ly, lz = r1[k], r1[3 + k], r1[6 + k]
        elif k < 6:
            lx, ly, lz = r2[k - 3], r2[k], r2[k + 3]
        else:
            i, j = (k - 6) // 3, (k - 6) % 3
            ux, uy, uz = r1[i], r1[3 + i], r1[6 + i]
            vx, vy, vz = r2[j], r2[3 + j], r2[6 + j]
            lx, ly, lz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
            norm = math.sqrt(lx * lx + ly * ly + lz * lz)
            if norm < 1e-9:
                continue
            lx, ly, lz = lx / norm, ly / norm, lz / norm
        extent = (a0 * abs(lx * r1[0] + ly * r1[3] + lz * r1[6])
                  + a1 * abs(lx * r1[1] + ly * r1[4] + lz * r1[7])
                  + a2 * abs(lx * r1[2] + ly * r1[5] + lz * r1[8])
                  + b0 * abs(lx * r2[0] + ly * r2[3] + lz * r2[6])
                  + b1 * abs(lx * r2[1] + ly * r2[4] + lz * r2[7])
                  + b2 * abs(lx * r2[2] + ly * r2[5] + lz * r2[8]))
        gap = abs(lx * dx + ly * dy + lz * dz) - extent
        if gap > best:
            best = gap
    return best


@njit(cache=True)
def _plane_height(px, py, pz, c, r):
    """Height of a world point above a plane (its z axis; the half-space below is solid)."""
    return r[2] * (px - c[0]) + r[5] * (py - c[1]) + r[8] * (pz - c[2])


@njit(cache=True)
def _capsule_ends(c, r, half):
    return (c[0] - half * r[2], c[1] - half * r[5], c[2] - half * r[8],
            c[0] + half * r[2], c[1] + half * r[5], c[2] + half * r[8])


@njit(cache=True)
def _bound_shapes(ka, ca, ra, sa0, sa1, sa2, kb, cb, rb, sb0, sb1, sb2):
    """Lower bound on the distance of two containers of kinds SPHERE/CAPSULE/BOX/PLANE."""
    if ka > kb:
        return _bound_ordered(kb, cb, rb, sb0, sb1, sb2, ka, ca, ra, sa0, sa1, sa2)
    return _bound_ordered(ka, ca, ra, sa0, sa1, sa2, kb, cb, rb, sb0, sb1, sb2)


@njit(cache=True)
def _bound_ordered(ka, ca, ra, sa0, sa1, sa2, kb, cb, rb, sb0, sb1, sb2):
    """:func:`_bound_shapes` with ``ka <= kb``."""
    if ka == SPHERE:
        if kb == SPHERE:
            dx, dy, dz = ca[0] - cb[0], ca[1] - cb[1], ca[2] - cb[2]
            return math.sqrt(dx * dx + dy * dy + dz * dz) - sa0 - sb0
        if kb == CAPSULE:
            e = _capsule_ends(cb, rb, sb1)
            return math.sqrt(_point_segment_sq(ca[0], ca[1], ca[2], e[0], e[1], e[2],
                                               e[3], e[4], e[5])) - sa0 - sb0
        if kb == BOX:
            return _point_box(ca[0], ca[1], ca[2], cb, rb, sb0, sb1, sb2) - sa0
        return _plane_height(ca[0], ca[1], ca[2], cb, rb) - sa0
    if ka == CAPSULE:
        e = _capsule_ends(ca, ra, sa1)
        if kb == CAPSULE:
            f = _capsule_ends(cb, rb, sb1)
            return math.sqrt(_segment_segment_sq(e[0], e[1], e[2], e[3], e[4], e[5],
                                                 f[0], f[1], f[2], f[3], f[4], f[5])
                             ) - sa0 - sb0
        if kb == BOX:
            return _segment_box(e[0], e[1], e[2], e[3], e[4], e[5], cb, rb, sb0, sb1, sb2) - sa0
        return min(_plane_height(e[0], e[1], e[2], cb, rb),
                   _plane_height(e[3], e[4], e[5], cb, rb)) - sa0
    if ka == BOX:
        if kb == BOX:
            return _box_box(ca, ra, sa0, sa1, sa2, cb, rb, sb0, sb1, sb2)
        reach = (sa0 * abs(rb[2] * ra[0] + rb[5] * ra[3] + rb[8] * ra[6])
                 + sa1 * abs(rb[2] * ra[1] + rb[5] * ra[4] + rb[8] * ra[7])
                 + sa2 * abs(rb[2] * ra[2] + rb[5] * ra[5] + rb[8] * ra[8]))
        return _plane_height(ca[0], ca[1], ca[2], cb, rb) - reach
    return -math.inf


@njit(cache=True)
def _bound_pair(ka, ca, ra, sa, kb, cb, rb, sb):
    """Lower bound on the distance of two slots' containers, any kinds: a cylinder is held
    by the capsule of its radius over its axis and by its box, so the larger of the two
    bounds holds; an unbounded kind gives −inf (MuJoCo decides)."""
    if ka == UNBOUNDED or kb == UNBOUNDED or (ka == PLANE and kb == PLANE):
        return -math.inf
    best = -math.inf
    for use_a in range(2 if ka == CYLINDER else 1):
        ta, a0, a1, a2 = ka, sa[0], sa[1], sa[2]
        if ka == CYLINDER:
            ta, a0, a1, a2 = (BOX, sa[0], sa[0], sa[1]) if use_a else (CAPSULE, sa[0], sa[1], 0.0)
        for use_b in range(2 if kb == CYLINDER else 1):
            tb, b0, b1, b2 = kb, sb[0], sb[1], sb[2]
            if kb == CYLINDER:
                tb, b0, b1, b2 = ((BOX, sb[0], sb[0], sb[1]) if use_b
                                  else (CAPSULE, sb[0], sb[1], 0.0))
            value = _bound_shapes(ta, ca, ra, a0, a1, a2, tb, cb, rb, b0, b1, b2)
            if value > best:
                best = value
    return best


# ----------------------------------------------------------------- forward kinematics
@njit(cache=True)
def _turn(m00, m01, m02, m10, m11, m12, m20, m21, m22, axis, c, s):
    """The frame m times the rotation by (c, s) = (cos θ, sin θ) about a local unit axis
    (``axis``, (3,)), applied on the right (Rodrigues' formula)."""
    ux, uy, uz = axis[0], axis[1], axis[2]
    t = 1.0 - c
    r00, r01, r02 = c + t * ux * ux, t * ux * uy - s * uz, t * ux * uz + s * uy
    r10, r11, r12 = t * ux * uy + s * uz, c + t * uy * uy, t * uy * uz - s * ux
    r20, r21, r22 = t * ux * uz - s * uy, t * uy * uz + s * ux, c + t * uz * uz
    return (m00 * r00 + m01 * r10 + m02 * r20, m00 * r01 + m01 * r11 + m02 * r21,
            m00 * r02 + m01 * r12 + m02 * r22,
            m10 * r00 + m11 * r10 + m12 * r20, m10 * r01 + m11 * r11 + m12 * r21,
            m10 * r02 + m11 * r12 + m12 * r22,
            m20 * r00 + m21 * r10 + m22 * r20, m20 * r01 + m21 * r11 + m22 * r21,
            m20 * r02 + m21 * r12 + m22 * r22)


@njit(cache=True, inline="always")
def _forward(body_parent, body_pos, body_rot, body_jntadr, body_jntnum, body_flags,
             jnt_type, jnt_qposadr, jnt_pos, jnt_axis, jnt_axis_code, qpos0, qpos, xpos,
             xmat):
    """Body frames for ``qpos``, composed as ``mj_kinematics`` does (world = xmat @ local):
    the parent's frame times the body offset, then each joint in order (a slide shifts
    along its axis, a hinge turns about its anchor), joint values relative to ``qpos0``.

    Static bodies (``body_flags`` bit 0) keep the frames set at construction; bit 1 marks
    an identity body rotation. Hinges about a local ±x/±y/±z axis (``jnt_axis_code`` 0–5)
    turn two columns only. The frame being built lives in scalars: stores to ``xmat``
    would otherwise force reloads of the parent's frame (the two may alias).
    """
    for b in range(1, len(body_parent)):
        flags = body_flags[b]
        if flags & 1:
            continue
        p = body_parent[b]
        p00, p01, p02 = xmat[p, 0, 0], xmat[p, 0, 1], xmat[p, 0, 2]
        p10, p11, p12 = xmat[p, 1, 0], xmat[p, 1, 1], xmat[p, 1, 2]
        p20, p21, p22 = xmat[p, 2, 0], xmat[p, 2, 1], xmat[p, 2, 2]
        bx, by, bz = body_pos[b, 0], body_pos[b, 1], body_pos[b, 2]
        x0 = xpos[p, 0] + p00 * bx + p01 * by + p02 * bz
        x1 = xpos[p, 1] + p10 * bx + p11 * by + p12 * bz
        x2 = xpos[p, 2] + p20 * bx + p21 * by + p22 * bz
        if flags & 2:
            m00, m01, m02 = p00, p01, p02
            m10, m11, m12 = p10, p11, p12
            m20, m21, m22 = p20, p21, p22
        else:
            r = body_rot[b]
            m00 = p00 * r[0, 0] + p01 * r[1, 0] + p02 * r[2, 0]
            m01 = p00 * r[0, 1] + p01 * r[1, 1] + p02 * r[2, 1]
            m02 = p00 * r[0, 2] + p01 * r[1, 2] + p02 * r[2, 2]
            m10 = p10 * r[0, 0] + p11 * r[1, 0] + p12 * r[2, 0]
            m11 = p10 * r[0, 1] + p11 * r[1, 1] + p12 * r[2, 1]
            m12 = p10 * r[0, 2] + p11 * r[1, 2] + p12 * r[2, 2]
            m20 = p20 * r[0, 0] + p21 * r[1, 0] + p22 * r[2, 0]
            m21 = p20 * r[0, 1] + p21 * r[1, 1] + p22 * r[2, 1]
            m22 = p20 * r[0, 2] + p21 * r[1, 2] + p22 * r[2, 2]
        for j in range(body_jntadr[b], body_jntadr[b] + body_jntnum[b]):
            adr = jnt_qposadr[j]
            value = qpos[adr] - qpos0[adr]
            if jnt_type[j] == _SLIDE:
                ux, uy, uz = jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2]
                x0 += value * (m00 * ux + m01 * uy + m02 * uz)
                x1 += value * (m10 * ux + m11 * uy + m12 * uz)
                x2 += value * (m20 * ux + m21 * uy + m22 * uz)
                continue
            px, py, pz = jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2]
            a0 = x0 + m00 * px + m01 * py + m02 * pz
            a1 = x1 + m10 * px + m11 * py + m12 * pz
            a2 = x2 + m20 * px + m21 * py + m22 * pz
            code = jnt_axis_code[j]
            c = math.cos(value)
            s = math.sin(value) if code < 3 or code == 6 else -math.sin(value)
            axis = code % 3 if code < 6 else 3
            if axis == 0:  # columns 1, 2 turn: m·Rx
                m01, m02 = c * m01 + s * m02, c * m02 - s * m01
                m11, m12 = c * m11 + s * m12, c * m12 - s * m11
                m21, m22 = c * m21 + s * m22, c * m22 - s * m21
            elif axis == 1:  # columns 2, 0 turn: m·Ry
                m00, m02 = c * m00 - s * m02, c * m02 + s * m00
                m10, m12 = c * m10 - s * m12, c * m12 + s * m10
                m20, m22 = c * m20 - s * m22, c * m22 + s * m20
            elif axis == 2:  # columns 0, 1 turn: m·Rz
                m00, m01 = c * m00 + s * m01, c * m01 - s * m00
                m10, m11 = c * m10 + s * m11, c * m11 - s * m10
                m20, m21 = c * m20 + s * m21, c * m21 - s * m20
            else:
                m00, m01, m02, m10, m11, m12, m20, m21, m22 = _turn(
                    m00, m01, m02, m10, m11, m12, m20, m21, m22, jnt_axis[j], c, s)
            x0 = a0 - (m00 * px + m01 * py + m02 * pz)
            x1 = a1 - (m10 * px + m11 * py + m12 * pz)
            x2 = a2 - (m20 * px + m21 * py + m22 * pz)
        xpos[b, 0], xpos[b, 1], xpos[b, 2] = x0, x1, x2
        xmat[b, 0, 0], xmat[b, 0, 1], xmat[b, 0, 2] = m00, m01, m02
        xmat[b, 1, 0], xmat[b, 1, 1], xmat[b, 1, 2] = m10, m11, m12
        xmat[b, 2, 0], xmat[b, 2, 1], xmat[b, 2, 2] = m20, m21, m22


@njit(cache=True, inline="always")
def _place_slots(slot_body, slot_static, slot_pos, slot_rot, xpos, xmat, wpos, wrot):
    """World frames of the moving slots' containers (static slots were placed once)."""
    for s in range(len(slot_body)):
        if slot_static[s]:
            continue
        b = slot_body[s]
        m00, m01, m02 = xmat[b, 0, 0], xmat[b, 0, 1], xmat[b, 0, 2]
        m10, m11, m12 = xmat[b, 1, 0], xmat[b, 1, 1], xmat[b, 1, 2]
        m20, m21, m22 = xmat[b, 2, 0], xmat[b, 2, 1], xmat[b, 2, 2]
        px, py, pz = slot_pos[s, 0], slot_pos[s, 1], slot_pos[s, 2]
        wpos[s, 0] = xpos[b, 0] + m00 * px + m01 * py + m02 * pz
        wpos[s, 1] = xpos[b, 1] + m10 * px + m11 * py + m12 * pz
        wpos[s, 2] = xpos[b, 2] + m20 * px + m21 * py + m22 * pz
        r = slot_rot[s]
        for k in range(3):
            r0, r1, r2 = r[0, k], r[1, k], r[2, k]
            wrot[s, 0, k] = m00 * r0 + m01 * r1 + m02 * r2
            wrot[s, 1, k] = m10 * r0 + m11 * r1 + m12 * r2
            wrot[s, 2, k] = m20 * r0 + m21 * r1 + m22 * r2


# ------------------------------------------------------------------- samples and paths
@njit(cache=True, inline="always")
def _local_speed(a, motion, xpos, xmat, jnt_pos, jnt_axis, jnt_type, wpos, radius, dq):
    """V0: a bound on the speed of any point of slot ``a``'s bounding sphere at this
    sample, per unit path parameter, from the actual distances of its centre to the hinge
    axes that move it (plus the sphere's radius), slides at full speed."""
    slot_moved, jnt_body = motion[1], motion[2]
    speed = 0.0
    for j in range(len(jnt_body)):
        if not slot_moved[a, j] or dq[j] == 0.0:
            continue
        if jnt_type[j] == _SLIDE:
            speed += dq[j]
            continue
        b = jnt_body[j]
        # The hinge's anchor and axis in the world (a turn about it leaves both in place).
        px, py, pz = jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2]
        ax, ay, az = jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2]
        d = np.empty(3)
        u = np.empty(3)
        for i in range(3):
            d[i] = wpos[a, i] - (xpos[b, i] + xmat[b, i, 0] * px + xmat[b, i, 1] * py
                                 + xmat[b, i, 2] * pz)
            u[i] = xmat[b, i, 0] * ax + xmat[b, i, 1] * ay + xmat[b, i, 2] * az
        c0, c1, c2 = d[1] * u[2] - d[2] * u[1], d[2] * u[0] - d[0] * u[2], d[0] * u[1] - d[1] * u[0]
        speed += dq[j] * (math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) + radius)
    return speed


@njit(cache=True, inline="always")
def _sample_step(tree, geometry, qpos, xpos, xmat, wpos, wrot, rates, coarse, cap, counters,
                 motion, local):
    """The free step around the sample ``qpos``: the largest s ≤ ``cap`` (in path
    parameter t) such that every pair stays farther than its margin for |t − t_i| ≤ s, from
    lower bounds only; −1 if some pair may be within its margin (MuJoCo must decide).

    Bounding spheres first (``coarse``: their step per pair); exact container bounds only
    for pairs whose sphere step is below the best step found so far, the nearest first.
    A static pair's step is the larger of two valid ones: at the global rate (lever arms
    over all configurations), and, with ``local`` = (dq, growth, speeds), from the
    configuration itself: a moving slot's points move at most V0 + W·|t − t_i| per unit t
    (V0 from its actual distances to the hinge axes, W how fast later joints can change
    those), so within s they cover at most V0·s + W·s²/2. ``local`` None: configurations
    only (no step needed beyond 0).
    """
    (body_parent, body_pos, body_rot, body_jntadr, body_jntnum, body_flags, jnt_type,
     jnt_qposadr, jnt_pos, jnt_axis, jnt_axis_code, qpos0) = tree
    (slot_body, slot_static, slot_pos, slot_rot, slot_type, slot_size, slot_radius,
     pair_a, pair_b, pair_margin, _, pair_reach, pair_kind, pair_fixed, slot_pairs) = geometry
    _forward(body_parent, body_pos, body_rot, body_jntadr, body_jntnum, body_flags,
             jnt_type, jnt_qposadr, jnt_pos, jnt_axis, jnt_axis_code, qpos0, qpos, xpos,
             xmat)
    _place_slots(slot_body, slot_static, slot_pos, slot_rot, xpos, xmat, wpos, wrot)
    if local is not None:
        local[2][:] = -1.0  # per-slot V0, computed when a pair needs it
    # Bounding spheres (a half-space for a plane) farther apart than the pair can close
    # within ``cap`` cannot limit the step: no sqrt, no division for them. The others are
    # kept, with their sphere step, in ``coarse`` (pair, step) rows.
    survivors, nearest, nearest_step = _sphere_steps(slot_body, slot_pairs, wpos, pair_b,
                                                     pair_reach, pair_kind, pair_fixed, rates,
                                                     cap, coarse)
    best = cap
    if nearest_step >= best:
        return best
    # Finer bounds, the nearest pair first (it usually sets ``best``), then every pair whose
    # coarser bound could still limit the step: a's bounding sphere against a static b's
    # container, then the two containers.
    for visit in range(-1, survivors):
        row = nearest if visit < 0 else visit
        if (visit >= 0 and row == nearest) or coarse[row, 1] >= best:
            continue
        k = int(coarse[row, 0])
        a, b = pair_a[k], pair_b[k]
        ca, cb, rb, sb = _centre(wpos, a), _centre(wpos, b), _rotation(wrot, b), _size(slot_size, b)
        sphere = -math.inf
        if slot_static[b] and slot_type[b] != PLANE:
            sphere = _bound_pair(SPHERE, ca, rb, (slot_radius[a], 0.0, 0.0), slot_type[b], cb,
                                 rb, sb) - pair_margin[k]
            if sphere > 0.0 and (rates[k] == 0.0 or sphere >= best * rates[k]):
                continue
        counters[2] += 1
        # Both are lower bounds of the same distance (the sphere holds a's container).
        gap = max(sphere, _bound_pair(slot_type[a], ca, _rotation(wrot, a), _size(slot_size, a),
                                      slot_type[b], cb, rb, sb) - pair_margin[k])
        if not gap > 0.0:
            return -1.0
        step = _rate_step(gap, rates[k])
        if local is not None and slot_static[b] and step < best:
            dq, growth, speeds = local
            if speeds[a] < 0.0:
                speeds[a] = _local_speed(a, motion, xpos, xmat, jnt_pos, jnt_axis, jnt_type,
                                         wpos, slot_radius[a], dq)
            step = _local_step(step, gap, speeds[a], growth[a])
        if step < best:
            best = step
    return best


@njit(cache=True, inline="always")
def _rate_step(gap, rate):
    """How far (in t) a pair ``gap`` (> 0) beyond its margin stays so, closing at ``rate``:
    unlimited for a pair that cannot approach."""
    return gap / rate if rate > 0.0 else math.inf


@njit(cache=True, inline="always")
def _sphere_steps(slot_body, slot_pairs, wpos, pair_b, pair_reach, pair_kind, pair_fixed,
                  rates, cap, coarse):
    """The bounding-sphere pass of :func:`_sample_step`: every pair that could limit the
    step within ``cap`` as a ``coarse`` row (pair, sphere step; −1 where the spheres may
    be within the margin). Returns (rows written, the row of the smallest step, that
    step; −1 and inf if none)."""
    survivors, nearest, nearest_step = 0, -1, math.inf
    for a in range(len(slot_body)):
        first, stop = slot_pairs[a], slot_pairs[a + 1]
        if first == stop:
            continue
        ax, ay, az = wpos[a, 0], wpos[a, 1], wpos[a, 2]
        for k in range(first, stop):
            reach = pair_reach[k]
            limit = reach + rates[k] * cap
            kind = pair_kind[k]
            if kind == 3:  # OUT_OF_REACH
                continue
            if kind == 1:  # a fixed half-space
                height = (pair_fixed[k, 3] * (ax - pair_fixed[k, 0])
                          + pair_fixed[k, 4] * (ay - pair_fixed[k, 1])
                          + pair_fixed[k, 5] * (az - pair_fixed[k, 2]))
                if height >= limit:
                    continue
                gap = height - reach
            else:
                if kind == 0:  # a fixed sphere
                    dx, dy, dz = ax - pair_fixed[k, 0], ay - pair_fixed[k, 1], az - pair_fixed[k, 2]
                else:  # slot b's sphere
                    b = pair_b[k]
                    dx, dy, dz = ax - wpos[b, 0], ay - wpos[b, 1], az - wpos[b, 2]
                squared = dx * dx + dy * dy + dz * dz
                if squared >= limit * limit:
                    continue
                gap = math.sqrt(squared) - reach
            step = _rate_step(gap, rates[k]) if gap > 0.0 else -1.0
            coarse[survivors, 0], coarse[survivors, 1] = k, step
            if step < nearest_step:
                nearest, nearest_step = survivors, step
            survivors += 1
    return survivors, nearest, nearest_step


@njit(cache=True, inline="always")
def _local_step(step, gap, v0, w):
    """A static pair's step from the configuration itself: a moving slot whose points move
    at most V0 + W·|t − t_i| per unit t covers at most V0·s + W·s²/2 within s, so the pair
    keeps ``gap`` for s < 2·gap/(V0 + √(V0² + 2·W·gap)); the larger of that and ``step``
    (the step at the global rate)."""
    root = math.sqrt(v0 * v0 + 2.0 * w * gap)
    if v0 + root > 0.0:
        step = max(step, 2.0 * gap / (v0 + root))
    return step


@njit(cache=True, inline="always")
def _centre(wpos, s):
    return (wpos[s, 0], wpos[s, 1], wpos[s, 2])


@njit(cache=True, inline="always")
def _size(size, s):
    return (size[s, 0], size[s, 1], size[s, 2])


@njit(cache=True, inline="always")
def _rotation(wrot, s):
    return (wrot[s, 0, 0], wrot[s, 0, 1], wrot[s, 0, 2], wrot[s, 1, 0], wrot[s, 1, 1],
            wrot[s, 1, 2], wrot[s, 2, 0], wrot[s, 2, 1], wrot[s, 2, 2])


@njit(cache=True)
def _exact_contacts(qpos, exact):
    """``mj_kinematics`` + ``mj_collision`` at ``qpos`` on the checker's ``MjData``
    (``exact``: its qpos and ncon views and the functions' addresses): the contact count."""
    data_qpos, ncon, kinematics, collision, model, data = exact
    for j in range(len(qpos)):
        data_qpos[j] = qpos[j]
    native.call_model_data(kinematics, model, data)
    native.call_model_data(collision, model, data)
    return ncon[0]


@njit(cache=True)
def _work(tree, geometry):
    """Scratch arrays of one kernel call: body frames (static ones preset), slot frames
    (static ones preset), per-pair rates and sphere steps."""
    body_xpos, body_xmat = tree[-2], tree[-1]
    slot_pos, slot_rot, pair_a = geometry[2], geometry[3], geometry[7]
    return (body_xpos.copy(), body_xmat.copy(), slot_pos.copy(), slot_rot.copy(),
            np.ones(len(pair_a)), np.empty((len(pair_a), 2)))


@njit(cache=True)
def _fill_qpos(qpos, qpos0, row):
    """``qpos`` = ``qpos0`` with its leading entries replaced by ``row``."""
    for j in range(len(qpos0)):
        qpos[j] = row[j] if j < len(row) else qpos0[j]


@njit(cache=True)
def path_steps(start_rows, end_rows, lever, resolution, out):
    """``out[m]`` = n = max(⌈D/δ − 1e−12⌉, 1) grid intervals of path m, where
    D = Σ_j lever_j·|Δq_j| summed in joint order (the one definition every backend uses,
    so a path has the same grid whether it is checked alone or in a batch). A start
    array with one row serves every end row."""
    for m in range(end_rows.shape[0]):
        start = start_rows[0] if start_rows.shape[0] == 1 else start_rows[m]
        bound = 0.0
        for j in range(end_rows.shape[1]):
            bound += lever[j] * abs(end_rows[m, j] - start[j])
        n = math.ceil(bound / resolution - 1e-12)
        out[m] = n if n > 1 else 1


@njit(cache=True)
def check_configurations(tree, geometry, motion, exact, rows, need, out, counters):
    """``out[i]``: MuJoCo's contact count at configuration ``rows[i]`` (its leading qpos
    entries; the rest stay at ``qpos0``): 0 where the bounds prove it free, MuJoCo's own
    count elsewhere. ``need`` > 0: rows are checked in order until ``need`` free ones are
    found; the rows after are not checked (``out`` −1). ``counters`` (4,): samples bounded,
    MuJoCo checks, exact pair bounds computed and MuJoCo checks that found no contact
    (samples free that the bounds could not prove free) are added to it."""
    xpos, xmat, wpos, wrot, rates, coarse = _work(tree, geometry)
    kinematic = tree[:12]
    qpos0 = tree[11]
    qpos = np.empty(len(qpos0))
    free = 0
    for i in range(rows.shape[0]):
        if need > 0 and free >= need:
            out[i] = -1
            continue
        _fill_qpos(qpos, qpos0, rows[i])
        counters[0] += 1
        step = _sample_step(kinematic, geometry, qpos, xpos, xmat, wpos, wrot, rates, coarse,
                            0.0, counters, motion, None)
        if step >= 0.0:
            out[i] = 0
        else:
            counters[1] += 1
            out[i] = _exact_contacts(qpos, exact)
            if out[i] == 0:
                counters[3] += 1
        if out[i] == 0:
            free += 1


@njit(cache=True)
def check_paths(tree, geometry, motion, exact, start_rows, end_rows, steps, first, out,
                counters):
    """``out[m]``: a grid index i of path m (q(t) = q0 + (i/n)(q1 − q0), n = ``steps[m]``;
    leading qpos entries, the rest at ``qpos0``) whose sample MuJoCo finds in contact, −1
    if none has one. With ``first`` it is the lowest such index; otherwise the first one
    found (the verdict is the same). A start array with one row serves every end row.

    Samples are visited in raked order: the middle of every unresolved interval of grid
    indices, breadth first; a sample the bounds prove free clears every index within its
    free step on both sides, any other is checked by MuJoCo."""
    xpos, xmat, wpos, wrot, rates, coarse = _work(tree, geometry)
    kinematic = tree[:12]
    qpos0 = tree[11]
    pair_lever = geometry[10]
    nq = pair_lever.shape[1]
    dof = end_rows.shape[1]
    delta, qpos, start = np.zeros(nq), np.empty(nq), np.empty(nq)
    slot_lever, slot_moved, _, jnt_down = motion
    jnt_type = tree[6]
    dq, growth, speeds = np.zeros(nq), np.zeros(len(slot_lever)), np.empty(len(slot_lever))
    local = (dq, growth, speeds)
    size = _queue_size(steps)
    queue_lo, queue_hi = np.empty(size, np.int64), np.empty(size, np.int64)
    for m in range(len(steps)):
        n = steps[m]
        _fill_qpos(start, qpos0, start_rows[0] if start_rows.shape[0] == 1 else start_rows[m])
        _path_rates(start, end_rows, m, pair_lever, delta, rates, dq)
        _axis_growth(slot_lever, slot_moved, jnt_down, jnt_type, dq, dof, growth)
        # The raked search stays here: as an inlined helper taking these arrays (numba
        # reference-counts them per call) it measured ~7 % slower on short paths.
        found = n + 1
        head, tail = 0, 1  # circular queue of intervals [lo, hi]
        queue_lo[0], queue_hi[0] = 0, n
        while head != tail:
            lo, hi = queue_lo[head], queue_hi[head]
            head = (head + 1) % size
            if hi >= found:
                hi = found - 1
            if lo > hi:
                continue
            mid = (lo + hi) // 2
            fraction = mid / n
            _path_sample(qpos, start, delta, fraction, dof)
            counters[0] += 1
            step = _sample_step(kinematic, geometry, qpos, xpos, xmat, wpos, wrot, rates,
                                coarse, max(mid - lo, hi - mid) / n, counters, motion, local)
            reach = 0
            if step < 0.0:
                counters[1] += 1
                if not _exact_contacts(qpos, exact):
                    counters[3] += 1  # the bounds could not prove a free sample free
                else:
                    found = mid
                    if not first:
                        break
                    tail = _push_interval(queue_lo, queue_hi, tail, lo, mid - 1)
                    continue
            else:
                scaled = step * n
                reach = n if scaled >= n else int(scaled)
            tail = _push_interval(queue_lo, queue_hi, tail, lo, mid - reach - 1)
            tail = _push_interval(queue_lo, queue_hi, tail, mid + reach + 1, hi)
        out[m] = found if found <= n else -1


@njit(cache=True, inline="always")
def _queue_size(steps):
    """Room for the interval queue of every path: its grid points, plus two."""
    size = 2
    for m in range(len(steps)):
        size = max(size, steps[m] + 2)
    return size


@njit(cache=True, inline="always")
def _path_rates(start, end_rows, m, pair_lever, delta, rates, dq):
    """Path ``m``'s joint change ``delta`` (its first dof entries; the rest stay 0), every
    pair's global rate (Σ_j lever_kj·|Δq_j|, in joint order) and ``dq`` = |Δq|."""
    npair, nq = pair_lever.shape
    dof = end_rows.shape[1]
    for j in range(dof):
        delta[j] = end_rows[m, j] - start[j]
    for k in range(npair):
        rate = 0.0
        for j in range(dof):
            rate += pair_lever[k, j] * abs(delta[j])
        rates[k] = rate
    for j in range(nq):
        dq[j] = abs(delta[j])


@njit(cache=True, inline="always")
def _axis_growth(slot_lever, slot_moved, jnt_down, jnt_type, dq, dof, growth):
    """W per slot (``growth``): how fast later joints can change the slot's distances to
    the hinge axes that move it, along a path of joint change ``dq``."""
    for a in range(len(growth)):
        total = 0.0
        for j in range(dof):
            if slot_moved[a, j] and jnt_type[j] != _SLIDE and dq[j] > 0.0:
                later = 0.0
                for i in range(dof):
                    if jnt_down[j, i] and slot_moved[a, i]:
                        later += slot_lever[a, i] * dq[i]
                total += dq[j] * later
        growth[a] = total


@njit(cache=True, inline="always")
def _path_sample(qpos, start, delta, fraction, dof):
    """``qpos`` at ``fraction`` of the path: start + fraction·delta in the leading dof
    entries, the start (``qpos0``) in the rest."""
    for j in range(len(qpos)):
        qpos[j] = start[j] + fraction * delta[j] if j < dof else start[j]


@njit(cache=True, inline="always")
def _push_interval(queue_lo, queue_hi, tail, lo, hi):
    """Queue the interval [lo, hi] unless it is empty; returns the new tail."""
    if lo <= hi:
        queue_lo[tail], queue_hi[tail] = lo, hi
        tail = (tail + 1) % len(queue_lo)
    return tail


# --------------------------------------------------------------------------- the filter
class CompiledFilter:
    """The kernels bound to one checker's model and ``MjData`` (which must outlive it).

    ``model`` carries the checker's margins; ``pairs`` are its candidate pairs.
    Configurations are the leading ``dof`` qpos entries (the rest stay at ``qpos0``).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, dof: int,
                 pairs: np.ndarray) -> None:
        self.scene = compile_scene(model, dof, pairs)
        self._model, self._data = model, data
        self._exact = (data.qpos, native.ncon_view(data),
                       native.function_address("mj_kinematics"),
                       native.function_address("mj_collision"), model._address, data._address)
        # The kernels' leading arguments, built once (the arrays are refreshed in place).
        self._scene_arguments = (self.scene.tree, self.scene.geometry, self.scene.motion,
                                 self._exact)
        #: Samples bounded, MuJoCo checks, exact pair bounds, MuJoCo checks that found no
        #: contact: totals since construction (benchmarks and tests read them).
        self.counters = np.zeros(4, dtype=np.int64)

    def refresh_static(self, geoms: np.ndarray | None = None) -> None:
        """Follow changed static geoms of the model (see :func:`refresh_static`)."""
        refresh_static(self.scene, self._model, geoms)

    def contacts(self, rows: np.ndarray, need: int = 0) -> np.ndarray:
        """(M,) contact counts at configurations ``rows`` (M, dof): 0 where proven free.
        ``need`` > 0: only until ``need`` free rows are found (the rest −1, unchecked)."""
        out = np.empty(len(rows), dtype=np.int64)
        check_configurations(*self._scene_arguments, rows, need, out, self.counters)
        return out

    def paths(self, start_rows: np.ndarray, end_rows: np.ndarray, steps: np.ndarray,
              first: bool) -> np.ndarray:
        """(M,) grid index of a colliding sample per path (−1: free), the lowest with
        ``first``; ``start_rows`` (M or 1, dof), ``end_rows`` (M, dof), ``steps`` (M,)."""
        out = np.empty(len(end_rows), dtype=np.int64)
        check_paths(*self._scene_arguments, start_rows, end_rows, steps, first, out,
                    self.counters)
        return out


def warm_up() -> None:
    """Compile (or load from numba's on-disk cache) every kernel with the argument types
    the checker passes, on a small model: ``make`` runs it once before the tests, so
    parallel test processes load the cache instead of compiling each."""
    from .collision import CollisionChecker
    from .model import build_model

    model = build_model("anthropomorphic", "random_clutter")
    for pad in (True, False):
        checker = CollisionChecker(model, dof=6, pad=pad, backend="compiled")
        checker.refresh_static()
        q = np.zeros((2, 6))
        q[1, 1] = 0.5
        checker.collides(q)
        checker.check_paths(q[0], q[1])
        checker.paths_collide(q[0], q)
        checker.paths_collide(q, q[::-1])


if __name__ == "__main__":
    warm_up()
