"""Distances of an env's geoms measured by a second collision library (coal), for the
tests and benchmarks that check the collision checker from outside.

:class:`Measure` places every geom by MuJoCo's forward kinematics and asks coal for the
signed distance of geom pairs: the pairs the checker tests between their **collision**
geoms, the same body pairs between their **drawn** (visual) geoms, and the drawn geoms of
the body pairs the model excludes explicitly other than parent and child. coal is not a
dependency of the package (the ``dev`` extra installs it); importing this module needs it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

import coal
import gymnasium as gym
import mujoco
import numpy as np

from ikbranch_gym.envs.models.builders import VISUAL_GROUP

if TYPE_CHECKING:
    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv

#: Pairs whose bounding spheres are farther apart than this are not measured (m).
BROAD_PHASE = 0.05


def _shape(model: mujoco.MjModel, g: int) -> coal.ShapeBase | None:
    """coal's shape of geom ``g`` in the geom's frame (None: a type not measured)."""
    kind, size = model.geom_type[g], model.geom_size[g]
    if kind == mujoco.mjtGeom.mjGEOM_PLANE:
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
        drawn: list[tuple[int, int]] = []
        for b1, b2 in sorted(bodies):
            for g1 in self._drawn(b1):
                drawn += [(g1, g2) for g2 in self._drawn(b2)]
        self.drawn = self._geom_pairs(np.array(drawn, dtype=np.int64).reshape(-1, 2))
        # Body pairs the model excludes explicitly that are not parent and child (e.g. a
        # wrist's housings): their drawn geoms, measured apart (the checker never tests
        # them; a parent and its child meet at their joint by design).
        excluded: list[tuple[int, int]] = []
        parent = model.body_parentid
        for signature in model.exclude_signature.tolist():
            b1, b2 = signature >> 16, signature & 0xFFFF
            if parent[b1] == b2 or parent[b2] == b1:
                continue
            for g1 in self._drawn(b1):
                excluded += [(g1, g2) for g2 in self._drawn(b2)]
        self.excluded = self._geom_pairs(np.array(excluded, dtype=np.int64).reshape(-1, 2))
        self.refresh()
        self.request = coal.DistanceRequest()
        self.request.enable_signed_distance = True

    def refresh(self) -> None:
        """coal's shapes of the model's geoms now (a reset lays a clutter of new sizes)."""
        self.shapes = {g: _shape(self.model, g)
                       for pairs in (self.collision, self.drawn, self.excluded)
                       for g in pairs.ravel().tolist()}

    def _drawn(self, body: int) -> list[int]:
        model = self.model
        geoms = np.flatnonzero(model.geom_bodyid == body)
        planes = [int(g) for g in geoms if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE]
        return planes + [int(g) for g in geoms if model.geom_group[g] == VISUAL_GROUP]

    def _geom_pairs(self, pairs: np.ndarray) -> np.ndarray:
        """``pairs`` whose two shapes coal measures (every primitive; hfields are not)."""
        model = self.model
        keep = [(int(a), int(b)) for a, b in pairs
                if _shape(model, int(a)) is not None and _shape(model, int(b)) is not None]
        return np.array(keep, dtype=np.int64).reshape(-1, 2)

    def distances(self, q: np.ndarray, pairs: np.ndarray) -> np.ndarray:
        """Signed distances of ``pairs`` at configuration ``q`` (inf beyond the broad
        phase)."""
        model, data = self.model, self.data
        data.qpos[: self.dof] = q
        mujoco.mj_kinematics(model, data)
        a, b = pairs[:, 0], pairs[:, 1]
        centre = np.linalg.norm(data.geom_xpos[a] - data.geom_xpos[b], axis=1)
        planar = (model.geom_type[a] == mujoco.mjtGeom.mjGEOM_PLANE) | (
            model.geom_type[b] == mujoco.mjtGeom.mjGEOM_PLANE)
        reach = model.geom_rbound[a] + model.geom_rbound[b]
        near = planar | (centre - reach < BROAD_PHASE)
        out = np.full(len(pairs), np.inf)
        for k in np.flatnonzero(near):
            out[k] = self._distance(int(a[k]), int(b[k]))
        return out

    def _distance(self, g1: int, g2: int) -> float:
        data = self.data
        t1 = coal.Transform3s(data.geom_xmat[g1].reshape(3, 3), data.geom_xpos[g1])
        t2 = coal.Transform3s(data.geom_xmat[g2].reshape(3, 3), data.geom_xpos[g2])
        result = coal.DistanceResult()
        return float(coal.distance(self.shapes[g1], t1, self.shapes[g2], t2, self.request,
                                   result))
