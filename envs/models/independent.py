"""Distances of an env's geoms measured by a second collision library (coal), for the
tests and benchmarks that check the collision checker from outside.

:class:`Measure` places every geom by MuJoCo's forward kinematics and asks coal for the
signed distance of geom pairs: the pairs the checker tests between their **collision**
geoms, the same body pairs between their **drawn** (visual) geoms, and the drawn geoms of
the body pairs the model excludes explicitly other than a joint's own two sides.
:meth:`Measure.certify` bounds the distances along a whole straight joint-space move, not
only at samples: with its own bound on how fast any point of a body can move (lever arms
from the model's offsets and slide strokes, not the checker's), two measured distances
d0, d1 at the ends of an interval on which the pair's points move relatively at most M
leave at least (d0 + d1 − M)/2 between them; intervals that bound is not positive for are
halved until it is, or until a penetration is measured. coal is not a dependency of the
package (the ``dev`` extra installs it); importing this module needs it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import coal
import gymnasium as gym
import mujoco
import numpy as np

from ikbranch_gym.envs.models.builders import VISUAL_GROUP
from ikbranch_gym.envs.models.collision import PLANE

if TYPE_CHECKING:
    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv

#: Pairs whose bounding spheres are farther apart than this (a sphere: farther above a
#: plane) are not measured (m).
BROAD_PHASE = 0.05


def _shape(model: mujoco.MjModel, g: int) -> coal.ShapeBase | None:
    """coal's shape of geom ``g`` in the geom's frame (None: a type not measured)."""
    kind, size = model.geom_type[g], model.geom_size[g]
    if kind == PLANE:
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return coal.Sphere(size[0])
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return coal.Capsule(size[0], 2 * size[1])
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return coal.Cylinder(size[0], 2 * size[1])
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return coal.Box(*(2 * size))
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        # The collision meshes are convex (boxes as meshes): their vertices' hull.
        start, count = model.mesh_vertadr[model.geom_dataid[g]], model.mesh_vertnum[
            model.geom_dataid[g]]
        vertices = model.mesh_vert[start:start + count].astype(np.float64)
        # Mesh vertices are stored in the geom's frame.
        points = coal.StdVec_Vec3s()
        for vertex in vertices:
            points.append(vertex)
        return coal.Convex.convexHull(points, False, "")
    return None


@dataclass(frozen=True)
class Clearance:
    """What :meth:`Measure.certify` found along a move: ``certified`` (every pair proven
    apart everywhere on it), the least distance measured (m; negative: a penetration),
    that geom pair, and the number of configurations measured."""

    certified: bool
    least: float
    pair: tuple
    evaluations: int


def joints_own_pair(model: mujoco.MjModel, b1: int, b2: int) -> bool:
    """Whether bodies ``b1`` and ``b2`` are a joint's two sides: one welded to the other or
    to its parent (MuJoCo's parent rule, with bodies fixed to the world as the world)."""
    weld, parent = model.body_weldid, model.body_parentid
    w1, w2 = int(weld[b1]), int(weld[b2])
    return w1 == w2 or int(weld[parent[w1]]) == w2 or int(weld[parent[w2]]) == w1


def hidden_body_pairs(model: mujoco.MjModel) -> list[tuple[int, int]]:
    """The body pairs the model excludes explicitly that are not a joint's own two sides:
    pairs whose contacts an exclusion hides."""
    pairs = []
    for signature in model.exclude_signature.tolist():
        b1, b2 = signature >> 16, signature & 0xFFFF
        if not joints_own_pair(model, b1, b2):
            pairs.append((b1, b2))
    return pairs


def lever_arms(model: mujoco.MjModel, dof: int) -> np.ndarray:
    """(nbody, dof): for joint j (qpos j, one joint per body) and a body b it moves, a bound
    on the distance of any point of b's geoms from j's anchor over every configuration: the
    anchor's offset, each body offset on the way to b (plus the stroke of a slide on it),
    and b's farthest geom; 1 for a slide (its points move as fast as the slide)."""
    lever = np.zeros((model.nbody, dof))
    reach = np.zeros(model.nbody)
    for g in range(model.ngeom):
        b = model.geom_bodyid[g]
        reach[b] = max(reach[b], np.linalg.norm(model.geom_pos[g]) + model.geom_rbound[g])
    stroke = np.zeros(model.nbody)
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            stroke[model.jnt_bodyid[j]] += np.abs(model.jnt_range[j]).max()
    for j in range(dof):
        joint = int(np.flatnonzero(model.jnt_qposadr == j)[0])
        home = int(model.jnt_bodyid[joint])
        slide = model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_SLIDE
        for b in range(1, model.nbody):
            chain, k = [], b
            while k not in (home, 0):
                chain.append(k)
                k = int(model.body_parentid[k])
            if k != home:
                continue  # joint j does not move body b
            offsets = sum(np.linalg.norm(model.body_pos[c]) + stroke[c] for c in chain)
            lever[b, j] = 1.0 if slide else (
                np.linalg.norm(model.jnt_pos[joint]) + offsets + reach[b])
    return lever


class Measure:
    """The body pairs an env's checker tests, their collision and drawn geoms as coal
    shapes (see the module docstring)."""

    def __init__(self, env: gym.Env) -> None:
        base = cast("IKBranchEnv", env.unwrapped)
        self.model, self.dof = base.model, base.arm.dof
        self.data = mujoco.MjData(self.model)
        model = self.model
        checker = base.checker
        bodies = {tuple(sorted((int(model.geom_bodyid[a]), int(model.geom_bodyid[b]))))
                  for a, b in checker._pairs}
        self.collision = self._geom_pairs(checker._pairs)
        # Allowed contacts (the env's ``allowed_contacts``, by collision geom name) are the
        # job, not a collision: their drawn twins are not measured either.
        allowed = {frozenset(pair) for pair in base.allowed_contacts}
        drawn: list[tuple[int, int]] = []
        for b1, b2 in sorted(bodies):
            for g1 in self._drawn(b1):
                drawn += [(g1, g2) for g2 in self._drawn(b2)
                          if frozenset((self._twin(g1), self._twin(g2))) not in allowed]
        self.drawn = self._geom_pairs(np.array(drawn, dtype=np.int64).reshape(-1, 2))
        # Body pairs the model excludes explicitly that are not a joint's own two sides
        # (e.g. the earlier models' wrist housings): their drawn geoms, measured apart (the
        # checker never tests them; a parent and its child meet at their joint by design).
        excluded: list[tuple[int, int]] = []
        for b1, b2 in hidden_body_pairs(model):
            for g1 in self._drawn(b1):
                excluded += [(g1, g2) for g2 in self._drawn(b2)]
        self.excluded = self._geom_pairs(np.array(excluded, dtype=np.int64).reshape(-1, 2))
        #: (nbody, dof): how far (m) any point of a body can be from joint j's axis in any
        #: configuration (1 for a slide): its speed is at most Σ_j |q̇_j| · lever[b, j].
        self.lever = lever_arms(model, self.dof)
        self.refresh()
        self.request = coal.DistanceRequest()
        self.request.enable_signed_distance = True

    def refresh(self) -> None:
        """coal's shapes of the model's geoms now (a reset lays a clutter of new sizes)."""
        self.shapes = {g: _shape(self.model, g)
                       for pairs in (self.collision, self.drawn, self.excluded)
                       for g in pairs.ravel().tolist()}

    def _twin(self, geom: int) -> str:
        """The collision geom's name a drawn geom stands for (``<name>_vis`` → ``<name>``)."""
        name = self.model.geom(geom).name
        return name[: -len("_vis")] if name.endswith("_vis") else name

    def _drawn(self, body: int) -> list[int]:
        model = self.model
        geoms = np.flatnonzero(model.geom_bodyid == body)
        planes = [int(g) for g in geoms if model.geom_type[g] == PLANE]
        return planes + [int(g) for g in geoms if model.geom_group[g] == VISUAL_GROUP]

    def _geom_pairs(self, pairs: np.ndarray) -> np.ndarray:
        """``pairs`` whose two shapes coal measures (every primitive; hfields are not)."""
        model = self.model
        keep = [(int(a), int(b)) for a, b in pairs
                if _shape(model, int(a)) is not None and _shape(model, int(b)) is not None]
        return np.array(keep, dtype=np.int64).reshape(-1, 2)

    def _gaps(self, q: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Lower bounds of the signed distances of ``pairs`` at ``q`` from bounding spheres
        alone (MuJoCo's ``geom_rbound``), placed by MuJoCo's forward kinematics: the gap
        between two spheres, or a sphere's height above a plane's halfspace (two planes:
        -inf)."""
        model, data = self.model, self.data
        data.qpos[: self.dof] = q
        mujoco.mj_kinematics(model, data)
        a, b = pairs[:, 0], pairs[:, 1]
        gap = (np.linalg.norm(data.geom_xpos[a] - data.geom_xpos[b], axis=1)
               - model.geom_rbound[a] - model.geom_rbound[b])
        for flat, other, rows in ((a, b, model.geom_type[a] == PLANE),
                                  (b, a, model.geom_type[b] == PLANE)):
            if rows.any():
                normal = data.geom_xmat[flat[rows]].reshape(-1, 3, 3)[:, :, 2]
                height = np.einsum("ij,ij->i", normal,
                                   data.geom_xpos[other[rows]] - data.geom_xpos[flat[rows]])
                gap[rows] = np.where(model.geom_type[other[rows]] == PLANE, -np.inf,
                                     height - model.geom_rbound[other[rows]])
        return gap

    def distances(self, q: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Signed distances of ``pairs`` at configuration ``q`` (inf where the bounding
        spheres are farther apart than the broad phase)."""
        out = np.full(len(pairs), np.inf)
        for k in np.flatnonzero(self._gaps(q, pairs) < BROAD_PHASE):
            out[k] = self._distance(int(pairs[k, 0]), int(pairs[k, 1]))
        return out

    def lower_bounds(self, q: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Lower bounds of the signed distances of ``pairs`` at ``q``: coal's distance
        where the pair's bounding spheres come within the broad phase, else their gap."""
        out = self._gaps(q, pairs)
        for k in np.flatnonzero(out < BROAD_PHASE):
            out[k] = self._distance(int(pairs[k, 0]), int(pairs[k, 1]))
        return out

    def certify(self, q0: np.ndarray, q1: np.ndarray, pairs: np.ndarray,
                shortest: float = 1e-7) -> Clearance:
        """Whether ``pairs`` stay apart along the straight move ``q0`` → ``q1`` (module
        docstring): intervals are halved until the bound proves each pair apart on it, a
        measured distance is negative, or an interval is shorter than ``shortest`` (of
        the move; then the move is not certified)."""
        q0, q1 = np.asarray(q0, dtype=float), np.asarray(q1, dtype=float)
        bodies = self.model.geom_bodyid[pairs]
        # Relative motion bound of each pair over the whole move.
        step = np.abs(q1 - q0)
        motion = (self.lever[bodies[:, 0]] + self.lever[bodies[:, 1]]) @ step
        ends = {0.0: self.lower_bounds(q0, pairs), 1.0: self.lower_bounds(q1, pairs)}
        evaluations = 2
        least = np.minimum(ends[0.0], ends[1.0])
        stack = [(0.0, 1.0, np.arange(len(pairs)))]
        while stack:
            lo, hi, open_ = stack.pop()
            d_lo, d_hi = ends[lo][open_], ends[hi][open_]
            bound = (d_lo + d_hi - motion[open_] * (hi - lo)) / 2
            open_ = open_[bound <= 0.0]
            if not len(open_):
                continue
            if (least[open_] < 0.0).any():
                k = int(open_[np.argmin(least[open_])])
                return Clearance(False, float(least[k]), tuple(pairs[k]), evaluations)
            if hi - lo < shortest:
                k = int(open_[0])
                return Clearance(False, float(least[k]), tuple(pairs[k]), evaluations)
            mid = (lo + hi) / 2
            if mid not in ends:
                ends[mid] = np.full(len(pairs), np.inf)
            ends[mid][open_] = self.lower_bounds(q0 + mid * (q1 - q0), pairs[open_])
            evaluations += 1
            least[open_] = np.minimum(least[open_], ends[mid][open_])
            stack += [(lo, mid, open_), (mid, hi, open_)]
        k = int(np.argmin(least)) if len(pairs) else 0
        return Clearance(True, float(least[k]) if len(pairs) else np.inf,
                         tuple(pairs[k]) if len(pairs) else (), evaluations)

    def _distance(self, g1: int, g2: int) -> float:
        data = self.data
        t1 = coal.Transform3s(data.geom_xmat[g1].reshape(3, 3), data.geom_xpos[g1])
        t2 = coal.Transform3s(data.geom_xmat[g2].reshape(3, 3), data.geom_xpos[g2])
        result = coal.DistanceResult()
        return float(coal.distance(self.shapes[g1], t1, self.shapes[g2], t2, self.request,
                                   result))
