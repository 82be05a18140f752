"""Scene files: a cell's obstacles from an MJCF file, merged with an arm's spec.

``docs/files.md`` describes the format, the base-pose convention, the errors and the
convex decomposition with its cache. In short:

* The file's ``<worldbody>`` holds the obstacles: static geoms (boxes, spheres, capsules,
  cylinders, ellipsoids, planes, meshes from STL/OBJ files, resolved by MuJoCo relative to
  the file's directory and its ``meshdir``). Any MJCF that MuJoCo compiles is read the way
  MuJoCo reads it (defaults, ``<include>``, angle units, ``fromto``): the file is compiled
  on its own and every geom is copied at its compiled world pose.
* **Frames.** The file's world frame is the *cell*. The arm's base stands at the pose of a
  site named ``arm_base`` in the file, or at ``base_pos``/``base_quat``/``base_rpy`` (never
  both), by default at the cell's origin. The compiled model's world frame is the arm's
  base frame (``arm.fk``'s frame, as for every other scene): obstacles and the floor
  (the cell's z = 0 plane) are mapped by inv(base). A site ``scene/cell`` marks the cell
  frame in the model; :meth:`SceneFile.cell_to_base` maps cell poses to base poses.
* Every geom with ``contype`` or ``conaffinity`` set becomes an obstacle: a visual twin
  ``scene/<name>_vis`` (group 2, no contacts) and a collision geom ``scene/<name>``
  (group 3, ``contype = conaffinity = COLLISION_BIT``) in a static body ``scene/<body>``.
  Geoms with both bits 0 are copied as visual twins only. Cylinders stay cylinders (the
  arm's own link twins are shortened capsules; an obstacle is never made smaller).
* MuJoCo collides a mesh as its convex hull. A mesh whose hull is larger than the mesh by
  more than ``CONVEXITY_TOL`` of the hull's volume (or that is not a closed, consistently
  oriented surface) is decomposed with CoACD into convex parts, one collision geom
  ``scene/<name>_part<k>`` each; the parts are cached beside the mesh file.

Rejected with a :class:`SceneFileError` (a ``ValueError``) naming the file and element: a
missing file, an MJCF MuJoCo cannot load or compile (MuJoCo's message), joints (obstacles
are static), mocap bodies, flexes, height fields and other geom types, a bad base pose.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import shutil
import tempfile
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.rotations import invert_pose, quaternion_matrix, rpy_matrix

from .builders import (
    COLLISION_BIT,
    COLLISION_GROUP,
    COLLISION_RGBA,
    VISUAL_GROUP,
    ArmTree,
    compile_spec,
)

LOG = logging.getLogger(__name__)

#: Name prefix of every element a scene file adds (geoms, bodies, meshes, the cell site).
PREFIX = "scene/"
#: Name of the site that places the arm's base in the cell.
BASE_SITE = "arm_base"
#: Largest accepted |‖q‖ − 1| of a base quaternion (not normalised beyond rounding).
QUATERNION_TOL = 1e-6
#: A closed mesh counts as convex when its convex hull exceeds its volume by at most this
#: fraction of the hull's volume (float32 vertices and flat facets of a convex solid give
#: < 1e-6; a cavity of 0.1 % of the hull is decomposed).
CONVEXITY_TOL = 1e-3
#: CoACD's parameters (``coacd.run_coacd``): its own defaults, with the seed fixed so the
#: decomposition is reproducible. ``coacd_options`` overrides any of them.
COACD_DEFAULTS: dict[str, Any] = {
    "threshold": 0.05,  # concavity bound, relative to the mesh's bounding-box diagonal
    "max_convex_hull": -1,  # no limit on the number of parts
    "preprocess_mode": "auto",  # remesh to a manifold only when the input is not one
    "preprocess_resolution": 50,
    "resolution": 2000,  # surface samples per concavity evaluation
    "mcts_nodes": 20,
    "mcts_iterations": 150,
    "mcts_max_depth": 3,
    "pca": False,
    "merge": True,
    "seed": 0,
}
#: ``decompose=``: "auto" (by the convexity rule), "always" (every collision mesh), "never"
#: (MuJoCo's hull; a cavity is then solid).
DECOMPOSE_MODES = ("auto", "always", "never")
#: The cache layout's version (part of every cache key).
CACHE_VERSION = 1

_G = mujoco.mjtGeom
_SUPPORTED = {
    _G.mjGEOM_PLANE: "plane",
    _G.mjGEOM_SPHERE: "sphere",
    _G.mjGEOM_CAPSULE: "capsule",
    _G.mjGEOM_ELLIPSOID: "ellipsoid",
    _G.mjGEOM_CYLINDER: "cylinder",
    _G.mjGEOM_BOX: "box",
    _G.mjGEOM_MESH: "mesh",
}


class SceneFileError(ValueError):
    """A bad scene file: ``path``, the ``element`` concerned (e.g. "body 'clamp'") or "",
    and the ``problem``."""

    def __init__(self, path: str | os.PathLike, problem: str, element: str = "") -> None:
        self.path = str(path)
        self.element = element
        self.problem = problem
        super().__init__(f"{self.path}: {element + ': ' if element else ''}{problem}")

    def __reduce__(self) -> tuple[type, tuple[str, str, str]]:
        # Pickles whole (e.g. raised in a vector env's worker).
        return type(self), (self.path, self.problem, self.element)


@dataclass(frozen=True, eq=False)
class MeshPart:
    """A triangle mesh in its geom's frame (m): ``vertices`` (V, 3), ``faces`` (F, 3)."""

    vertices: np.ndarray
    faces: np.ndarray


@dataclass(frozen=True, eq=False)
class Obstacle:
    """One geom of the file, posed in the **cell** frame.

    ``kind``: "box", "sphere", …, "mesh"; ``size`` MuJoCo's (3,) geom size; ``pos`` (3,),
    ``rotation`` (3, 3) its world pose in the file; ``collision``: the file gave it a
    contact bit; ``mesh``: the compiled mesh (its geom frame) for meshes; ``parts``: convex
    parts replacing the mesh in collisions (empty: the geom collides as itself).
    """

    name: str
    body: str
    kind: str
    size: np.ndarray
    pos: np.ndarray
    rotation: np.ndarray
    rgba: np.ndarray
    collision: bool
    mesh: MeshPart | None = None
    mesh_name: str = ""
    parts: tuple[MeshPart, ...] = ()


@dataclass(frozen=True, eq=False)
class MeshReport:
    """How a collision mesh was treated: whether it is a closed oriented surface, its
    volume and its hull's (m³, NaN where undefined), ``convex`` by the rule
    (``CONVEXITY_TOL``), the number of parts used (0: it collides as itself, also for a
    non-convex mesh under ``decompose="never"``), their cache folder (None: not
    decomposed) and whether the cache was reused."""

    name: str
    closed: bool
    volume: float
    hull_volume: float
    convex: bool
    n_parts: int
    cache_dir: Path | None
    cached: bool


@dataclass(frozen=True, eq=False)
class SceneFile:
    """A scene file read by :func:`load_scene_file`.

    ``base_pose`` (4, 4): the arm's base in the cell (cell ← base). ``obstacles`` in the
    cell frame; ``meshes``: one report per collision mesh.
    """

    path: Path
    base_pose: np.ndarray
    obstacles: tuple[Obstacle, ...]
    meshes: tuple[MeshReport, ...] = ()
    decompose: str = "auto"
    coacd_options: dict[str, Any] = field(default_factory=dict)

    @property
    def cell_from_base(self) -> np.ndarray:
        return self.base_pose

    @property
    def base_from_cell(self) -> np.ndarray:
        return invert_pose(self.base_pose)

    def cell_to_base(self, poses: ArrayLike) -> np.ndarray:
        """Poses (…, 4, 4) given in the cell frame, expressed in the arm's base frame."""
        return self.base_from_cell @ np.asarray(poses, dtype=np.float64)


# ------------------------------------------------------------------------------ base pose
def base_pose(base_pos: ArrayLike | None = None, base_quat: ArrayLike | None = None,
              base_rpy: ArrayLike | None = None) -> np.ndarray:
    """The arm's base in the cell (4, 4) from a position (m) and a unit quaternion
    (w, x, y, z) or roll-pitch-yaw (rad, R = Rz(yaw)·Ry(pitch)·Rx(roll), URDF's rpy).

    ``ValueError`` for both orientations, wrong shapes, NaN/inf, or a quaternion whose norm
    is not 1 within ``QUATERNION_TOL`` (never normalised beyond that rounding).
    """
    pose = np.eye(4)
    if base_quat is not None and base_rpy is not None:
        raise ValueError("give base_quat or base_rpy, not both")
    if base_pos is not None:
        pose[:3, 3] = _vector(base_pos, 3, "base_pos")
    if base_quat is not None:
        q = _vector(base_quat, 4, "base_quat")
        norm = math.sqrt(float(q @ q))
        if not abs(norm - 1.0) <= QUATERNION_TOL:
            raise ValueError(
                f"base_quat {q.tolist()} has norm {norm!r}, not 1 within {QUATERNION_TOL:g}"
            )
        pose[:3, :3] = quaternion_matrix(q)
    if base_rpy is not None:
        roll, pitch, yaw = _vector(base_rpy, 3, "base_rpy")
        pose[:3, :3] = rpy_matrix(roll, pitch, yaw)
    return pose


def _vector(value: ArrayLike, n: int, name: str) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {n} numbers, got {value!r}") from None
    if array.shape != (n,):
        raise ValueError(f"{name} must be {n} numbers, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or inf: {array.tolist()}")
    return array


# -------------------------------------------------------------------------------- reading
def load_scene_file(
    path: str | os.PathLike,
    *,
    base_pos: ArrayLike | None = None,
    base_quat: ArrayLike | None = None,
    base_rpy: ArrayLike | None = None,
    decompose: str = "auto",
    coacd_options: dict[str, Any] | None = None,
) -> SceneFile:
    """Read, compile and check a scene file; decompose its non-convex meshes (cached).

    See the module docstring for the conventions; ``SceneFileError`` for every problem.
    """
    path = Path(path)
    if decompose not in DECOMPOSE_MODES:
        raise ValueError(f"decompose must be one of {DECOMPOSE_MODES}, got {decompose!r}")
    options = dict(COACD_DEFAULTS)
    unknown = set(coacd_options or {}) - set(COACD_DEFAULTS)
    if unknown:
        raise ValueError(
            f"unknown coacd_options {sorted(unknown)}; known: {', '.join(COACD_DEFAULTS)}"
        )
    options.update(coacd_options or {})
    if not path.is_file():
        raise SceneFileError(path, "no such file" if not path.exists() else "not a file")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        sources = _mesh_sources(path, spec)
        model = spec.compile()
    except ValueError as exc:
        raise SceneFileError(path, f"MuJoCo cannot compile it: {_one_line(exc)}") from None
    _check_static(path, model)
    _check_mesh_sizes(path, model)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    pose = _base_pose(path, spec, model, data, base_pos, base_quat, base_rpy)

    collision_meshes = {
        int(model.geom_dataid[g]) for g in range(model.ngeom)
        if model.geom_type[g] == _G.mjGEOM_MESH
        and (model.geom_contype[g] or model.geom_conaffinity[g])
    }
    meshes: dict[int, tuple[MeshPart, tuple[MeshPart, ...], MeshReport]] = {}
    obstacles = []
    for g in range(model.ngeom):
        kind_id = int(model.geom_type[g])
        name = model.geom(g).name or f"geom{g}"
        if kind_id not in _SUPPORTED:
            raise SceneFileError(
                path, f"geom type {mujoco.mjtGeom(kind_id).name.removeprefix('mjGEOM_')} is "
                f"not supported (use {', '.join(_SUPPORTED.values())})", f"geom {name!r}",
            )
        kind = _SUPPORTED[kind_id]
        collision = bool(model.geom_contype[g] or model.geom_conaffinity[g])
        body = model.body(model.geom_bodyid[g]).name or f"body{model.geom_bodyid[g]}"
        matid = model.geom_matid[g]
        rgba = (model.mat_rgba[matid] if matid >= 0 else model.geom_rgba[g]).astype(np.float64)
        mesh: MeshPart | None = None
        parts: tuple[MeshPart, ...] = ()
        mesh_name = ""
        if kind == "mesh":
            mesh_id = int(model.geom_dataid[g])
            mesh_name = model.mesh(mesh_id).name or f"mesh{mesh_id}"
            if mesh_id not in meshes:
                meshes[mesh_id] = _treat_mesh(
                    path, model, mesh_id, mesh_name, sources.get(mesh_name),
                    decompose if mesh_id in collision_meshes else "never", options,
                )
            mesh, mesh_parts, _ = meshes[mesh_id]
            parts = mesh_parts if collision else ()
        obstacles.append(Obstacle(
            name=name, body=body, kind=kind, size=model.geom_size[g].copy(),
            pos=data.geom_xpos[g].copy(), rotation=data.geom_xmat[g].reshape(3, 3).copy(),
            rgba=rgba, collision=collision, mesh=mesh, mesh_name=mesh_name, parts=parts,
        ))
    reports = tuple(meshes[i][2] for i in sorted(collision_meshes))
    return SceneFile(path, pose, tuple(obstacles), reports, decompose, options)


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())


#: A mesh obstacle larger than this (m, the diagonal of its bounding box) is taken for
#: one written in millimetres: no robot cell is 100 m across.
MAX_MESH_SIZE = 100.0


def mesh_size(model: mujoco.MjModel, mesh: int) -> float:
    """The diagonal (m) of mesh ``mesh``'s bounding box as compiled (scaled, and turned to
    its principal axes as MuJoCo compiles a mesh)."""
    start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
    vertices = model.mesh_vert[start:start + count]
    return float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))


def _check_mesh_sizes(path: Path, model: mujoco.MjModel) -> None:
    for g in range(model.ngeom):
        if model.geom_type[g] != _G.mjGEOM_MESH:
            continue
        size = mesh_size(model, int(model.geom_dataid[g]))
        if size > MAX_MESH_SIZE:
            mesh = model.mesh(int(model.geom_dataid[g])).name or "its mesh"
            raise SceneFileError(
                path, f"mesh {mesh!r} spans {size:.3g} m: is it in millimetres? MuJoCo reads "
                "meshes in metres (or give the mesh scale=\"0.001 0.001 0.001\")",
                f"geom {model.geom(g).name or f'geom{g}'!r}")


def _check_static(path: Path, model: mujoco.MjModel) -> None:
    if model.njnt:  # the first joint of the file
        body = model.body(model.jnt_bodyid[0]).name or f"body{model.jnt_bodyid[0]}"
        joint = model.joint(0).name or "joint0"
        raise SceneFileError(
            path, f"has joint {joint!r}: obstacles must be static (no joint, no freejoint)",
            f"body {body!r}",
        )
    for b in range(model.nbody):
        if model.body_mocapid[b] >= 0:
            raise SceneFileError(path, "is a mocap body: obstacles must be static",
                                 f"body {model.body(b).name!r}")
    if model.nflex:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_FLEX, 0) or "flex0"
        raise SceneFileError(path, "flex (deformable) elements are not obstacles",
                             f"flex {name!r}")


def _base_pose(path: Path, spec: mujoco.MjSpec, model: mujoco.MjModel, data: mujoco.MjData,
               base_pos: ArrayLike | None, base_quat: ArrayLike | None,
               base_rpy: ArrayLike | None) -> np.ndarray:
    site = next((s for s in range(model.nsite) if model.site(s).name == BASE_SITE), None)
    given = [name for name, value in
             (("base_pos", base_pos), ("base_quat", base_quat), ("base_rpy", base_rpy))
             if value is not None]
    if site is None:
        try:
            return base_pose(base_pos, base_quat, base_rpy)
        except ValueError as exc:
            raise SceneFileError(path, str(exc)) from None
    element = f"site {BASE_SITE!r}"
    if given:
        raise SceneFileError(
            path, f"the file places the arm's base, and {', '.join(given)} "
            f"{'was' if len(given) == 1 else 'were'} given too: keep one", element,
        )
    raw = spec.site(BASE_SITE)
    if raw.alt.type == mujoco.mjtOrientation.mjORIENTATION_QUAT:
        norm = float(np.linalg.norm(raw.quat))
        if not abs(norm - 1.0) <= QUATERNION_TOL:
            raise SceneFileError(
                path, f"quat {raw.quat.tolist()} has norm {norm!r}, not 1 within "
                f"{QUATERNION_TOL:g} (MuJoCo would normalise it; write a unit quaternion)",
                element,
            )
    pose = np.eye(4)
    pose[:3, :3] = data.site_xmat[site].reshape(3, 3)
    pose[:3, 3] = data.site_xpos[site]
    return pose


# ---------------------------------------------------------------------------------- meshes
def _treat_mesh(path: Path, model: mujoco.MjModel, mesh_id: int, name: str,
                source: tuple[Path, str] | None, decompose: str, options: dict[str, Any],
                ) -> tuple[MeshPart, tuple[MeshPart, ...], MeshReport]:
    vertex0, nvert = model.mesh_vertadr[mesh_id], model.mesh_vertnum[mesh_id]
    face0, nface = model.mesh_faceadr[mesh_id], model.mesh_facenum[mesh_id]
    vertices32 = np.ascontiguousarray(model.mesh_vert[vertex0:vertex0 + nvert])
    faces = np.ascontiguousarray(model.mesh_face[face0:face0 + nface], dtype=np.int32)
    mesh = MeshPart(vertices32.astype(np.float64), faces)
    closed, volume = _closed_volume(mesh)
    hull = _hull_volume(model, mesh_id, mesh.vertices)
    convex = bool(closed and hull > 0 and hull - volume <= CONVEXITY_TOL * hull)
    if decompose == "never" or (decompose == "auto" and convex):
        report = MeshReport(name, closed, volume, hull, convex, 0, None, False)
        return mesh, (), report
    source_file, source_sha = source if source is not None else (None, None)
    key = _cache_key(vertices32, faces, options)
    cache_root = (Path(f"{source_file}.coacd") if source_file is not None
                  else path.with_name(f"{path.name}.coacd") / _safe(name))
    parts, cached = _cached_decomposition(
        path, cache_root, key, mesh, options, source_file, source_sha,
        info={"mesh": name, "mesh_pos": model.mesh_pos[mesh_id].tolist(),
              "mesh_quat": model.mesh_quat[mesh_id].tolist(),
              "scale": model.mesh_scale[mesh_id].tolist()},
    )
    report = MeshReport(name, closed, volume, hull, False, len(parts), cache_root / key[:16],
                        cached)
    return mesh, parts, report


def _closed_volume(mesh: MeshPart) -> tuple[bool, float]:
    """Whether the surface is closed and consistently oriented (every directed edge once,
    its reverse once, after merging coincident vertices), and its enclosed volume (NaN if
    not closed)."""
    unique, inverse = np.unique(mesh.vertices, axis=0, return_inverse=True)
    faces = inverse.reshape(-1)[mesh.faces]
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    if np.any(edges[:, 0] == edges[:, 1]):
        return False, math.nan
    n = len(unique)
    directed = edges[:, 0].astype(np.int64) * n + edges[:, 1]
    reverse = edges[:, 1].astype(np.int64) * n + edges[:, 0]
    values, counts = np.unique(directed, return_counts=True)
    closed = bool(np.all(counts == 1) and np.all(np.isin(reverse, values)))
    if not closed:
        return False, math.nan
    a, b, c = (unique[faces[:, k]] for k in range(3))
    volume = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
    return True, abs(volume)


def _hull_volume(model: mujoco.MjModel, mesh_id: int, vertices: np.ndarray) -> float:
    """Volume of MuJoCo's own convex hull of the mesh (``mesh_graph``), NaN if absent."""
    address = model.mesh_graphadr[mesh_id]
    if address < 0:
        return math.nan
    graph = model.mesh_graph[address:]
    nvert, nface = int(graph[0]), int(graph[1])
    start = 2 + nvert + nvert + (nvert + 3 * nface)
    faces = graph[start:start + 3 * nface].reshape(nface, 3)
    points = vertices[faces]
    centre = vertices[np.unique(faces)].mean(axis=0)
    a, b, c = (points[:, k] - centre for k in range(3))
    return float(np.abs(np.einsum("ij,ij->i", a, np.cross(b, c))).sum() / 6.0)


def _mesh_sources(path: Path, spec: mujoco.MjSpec) -> dict[str, tuple[Path, str]]:
    """Mesh name -> (its file as MuJoCo resolves it, sha256 of its bytes), for meshes read
    from files; the bytes are handed to MuJoCo with the spec.

    MuJoCo keeps a process-wide asset cache keyed by file name and modification time in
    whole seconds: a mesh rewritten within the second of its last load would come back
    stale. Given as in-memory assets, the mesh compiled is the one hashed here.
    """
    sources, assets = {}, dict(spec.assets)
    for mesh in spec.meshes:
        if not mesh.file:
            continue
        candidate = Path(mesh.file)
        if not candidate.is_absolute():
            base = Path(spec.modelfiledir) if spec.modelfiledir else path.parent
            candidate = base / (spec.meshdir or "") / mesh.file
        if not candidate.is_file():
            continue  # MuJoCo reports the missing file when it compiles
        data = candidate.read_bytes()
        sources[mesh.name] = (candidate, hashlib.sha256(data).hexdigest())
        for name in {mesh.file, os.path.join(spec.meshdir or "", mesh.file)}:
            assets[name] = data
    spec.assets = assets
    return sources


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name) or "mesh"


def _coacd_version() -> str:
    try:
        return metadata.version("coacd")
    except metadata.PackageNotFoundError:
        return "missing"


def _cache_key(vertices32: np.ndarray, faces: np.ndarray, options: dict) -> str:
    digest = hashlib.sha256()
    digest.update(f"ikbranch-coacd-v{CACHE_VERSION};coacd-{_coacd_version()};".encode())
    digest.update(json.dumps(options, sort_keys=True).encode())
    digest.update(np.ascontiguousarray(vertices32, dtype="<f4").tobytes())
    digest.update(np.ascontiguousarray(faces, dtype="<i4").tobytes())
    return digest.hexdigest()


def _cached_decomposition(
    path: Path, root: Path, key: str, mesh: MeshPart, options: dict, source: Path | None,
    source_sha: str | None, info: dict,
) -> tuple[tuple[MeshPart, ...], bool]:
    """The parts for ``key`` from ``root/key[:16]`` if valid, else from CoACD (written)."""
    directory = root / key[:16]
    parts = _read_cache(directory, key)
    if parts is not None:
        return parts, True
    started = time.perf_counter()
    raw = run_coacd(mesh.vertices, mesh.faces, options)
    elapsed = time.perf_counter() - started
    if not raw:
        raise SceneFileError(path, "CoACD returned no convex parts", f"mesh {info['mesh']!r}")
    LOG.info("%s: mesh %r decomposed into %d convex parts in %.2f s", path, info["mesh"],
             len(raw), elapsed)
    # The OBJ text holds every float's repr, so these parts equal what a later build reads.
    parts = tuple(MeshPart(np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int32))
                  for v, f in raw)
    try:
        _write_cache(root, directory, key, raw, options, source, source_sha, info, elapsed)
    except OSError as exc:  # e.g. a read-only checkout: decompose again next time
        LOG.warning("%s: cannot cache the decomposition of mesh %r in %s (%s)", path,
                    info["mesh"], directory, exc)
    return parts, False


def run_coacd(vertices: np.ndarray, faces: np.ndarray, options: dict) -> list:
    """``coacd.run_coacd`` on a triangle mesh: [(vertices (V, 3), faces (F, 3)), …]."""
    try:
        import coacd
    except ImportError as exc:  # pragma: no cover - coacd is a dependency
        raise ImportError(
            "non-convex meshes need CoACD: pip install coacd (or decompose='never')"
        ) from exc
    coacd.set_log_level("error")
    mesh = coacd.Mesh(np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int32))
    return coacd.run_coacd(mesh, **options)


def _read_cache(directory: Path, key: str) -> tuple[MeshPart, ...] | None:
    try:
        meta = json.loads((directory / "meta.json").read_text())
        if meta.get("key") != key:
            return None
        parts = []
        for entry in meta["parts"]:
            text = (directory / entry["file"]).read_bytes()
            if hashlib.sha256(text).hexdigest() != entry["sha256"]:
                return None
            parts.append(_parse_obj(text.decode()))
        return tuple(parts) if parts else None
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _write_cache(root: Path, directory: Path, key: str, raw: list, options: dict[str, Any],
                 source: Path | None, source_sha: str | None, info: dict[str, Any],
                 elapsed: float) -> None:
    root.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{key[:16]}-", dir=root))
    try:
        entries = []
        for k, (vertices, faces) in enumerate(raw):
            text = _format_obj(vertices, faces, f"CoACD part {k} of mesh {info['mesh']}")
            name = f"part_{k:03d}.obj"
            (staging / name).write_text(text)
            entries.append({"file": name, "sha256": hashlib.sha256(text.encode()).hexdigest(),
                            "vertices": len(vertices), "faces": len(faces)})
        meta = {
            "key": key, "cache_version": CACHE_VERSION, "coacd": _coacd_version(),
            "coacd_options": options, "source": None if source is None else str(source),
            "source_sha256": source_sha,
            "frame": "the geom frame of the compiled mesh (MuJoCo's: scale applied, origin at "
                     "the mesh's centroid, axes along its principal axes); file coordinates "
                     "= scale⁻¹·(R(mesh_quat)·v + mesh_pos)",
            **info, "seconds": round(elapsed, 3), "parts": entries,
        }
        (staging / "meta.json").write_text(json.dumps(meta, indent=1) + "\n")
        if _read_cache(directory, key) is None:  # else a parallel build has just written it
            if directory.exists():  # damaged
                shutil.rmtree(directory, ignore_errors=True)
            try:
                os.replace(staging, directory)
            except OSError:
                if _read_cache(directory, key) is None:  # not a parallel build's folder
                    raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    if source_sha is not None:
        _prune(root, directory, source_sha)


def _prune(root: Path, keep: Path, source_sha: str) -> None:
    """Remove cached decompositions of earlier contents of the same mesh file."""
    for other in root.iterdir():
        if other == keep or not other.is_dir() or other.name.startswith("."):
            continue
        try:
            meta = json.loads((other / "meta.json").read_text())
        except (OSError, ValueError):
            continue
        if meta.get("source_sha256") not in (None, source_sha):
            shutil.rmtree(other, ignore_errors=True)


def _format_obj(vertices: Iterable[Sequence[float]], faces: ArrayLike, comment: str) -> str:
    lines = [f"# {comment}"]
    lines += [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(faces, dtype=np.int64)]
    return "\n".join(lines) + "\n"


def _parse_obj(text: str) -> MeshPart:
    vertices, faces = [], []
    for line in text.splitlines():
        if line.startswith("v "):
            vertices.append([float(v) for v in line.split()[1:4]])
        elif line.startswith("f "):
            faces.append([int(v) - 1 for v in line.split()[1:4]])
    return MeshPart(np.array(vertices, dtype=np.float64).reshape(-1, 3),
                    np.array(faces, dtype=np.int32).reshape(-1, 3))


# -------------------------------------------------------------------------------- merging
def add_scene_file(
    spec: mujoco.MjSpec,
    scene: SceneFile,
    *,
    floor: bool = True,
) -> None:
    """Add ``scene``'s obstacles to ``spec`` (an arm's spec), in the arm's base frame.

    The spec's geom ``floor`` (if any) is moved to the cell's z = 0 plane, or deleted
    with ``floor=False``; a site ``scene/cell`` marks the cell frame.
    """
    to_base = scene.base_from_cell
    rotation_tb, offset_tb = to_base[:3, :3], to_base[:3, 3]
    floor_geom = next((g for g in spec.geoms if g.name == "floor"), None)
    if floor_geom is not None:
        if floor:
            floor_geom.pos = offset_tb.copy()
            floor_geom.quat = _quat(rotation_tb)
        else:
            spec.delete(floor_geom)
    site = spec.worldbody.add_site()
    site.name = f"{PREFIX}cell"
    site.pos, site.quat = offset_tb.copy(), _quat(rotation_tb)
    site.size = np.array([0.05, 0.0, 0.0])
    site.group = 5

    bodies: dict[str, mujoco.MjsBody] = {}
    mesh_assets: dict[str, str] = {}

    def body_for(name: str) -> mujoco.MjsBody:
        if name not in bodies:
            body = spec.worldbody.add_body()
            body.name = f"{PREFIX}{name}"
            bodies[name] = body
        return bodies[name]

    def mesh_asset(name: str, part: MeshPart) -> str:
        if name not in mesh_assets:
            asset = spec.add_mesh()
            asset.name = f"{PREFIX}{name}"
            asset.uservert = part.vertices.ravel()
            asset.userface = part.faces.ravel()
            asset.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
            mesh_assets[name] = asset.name
        return mesh_assets[name]

    for obstacle in scene.obstacles:
        body = body_for(obstacle.body)
        pos = rotation_tb @ obstacle.pos + offset_tb
        quat = _quat(rotation_tb @ obstacle.rotation)
        mesh = mesh_asset(obstacle.mesh_name, obstacle.mesh) if obstacle.mesh else ""
        _add_geom(body, f"{PREFIX}{obstacle.name}_vis", obstacle, pos, quat, mesh, visual=True)
        if not obstacle.collision:
            continue
        if obstacle.parts:
            for k, part in enumerate(obstacle.parts):
                part_mesh = mesh_asset(f"{obstacle.mesh_name}_part{k:03d}", part)
                _add_geom(body, f"{PREFIX}{obstacle.name}_part{k:03d}", obstacle, pos, quat,
                          part_mesh, visual=False)
        else:
            _add_geom(body, f"{PREFIX}{obstacle.name}", obstacle, pos, quat, mesh, visual=False)


def _quat(rotation: np.ndarray) -> np.ndarray:
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=np.float64).ravel())
    return quat


def _add_geom(body: mujoco.MjsBody, name: str, obstacle: Obstacle, pos: np.ndarray,
              quat: np.ndarray, mesh: str, *, visual: bool) -> None:
    geom = body.add_geom()
    geom.name = name
    geom.type = next(k for k, v in _SUPPORTED.items() if v == obstacle.kind)
    geom.size = obstacle.size.copy()
    geom.pos, geom.quat = pos, quat
    if mesh:
        geom.meshname = mesh
    if visual:
        geom.contype = geom.conaffinity = 0
        geom.group = VISUAL_GROUP
        geom.rgba = obstacle.rgba
    else:
        geom.contype = geom.conaffinity = COLLISION_BIT
        geom.group = COLLISION_GROUP
        geom.rgba = np.asarray(COLLISION_RGBA, dtype=np.float64)
    geom.density = 0.0  # static: the world carries them


# ---------------------------------------------------------------------------- the builder
def file_scene(
    spec: mujoco.MjSpec,
    arm: Arm,
    tree: ArmTree,
    *,
    scene_file: str | os.PathLike | None = None,
    base_pos: Sequence[float] | None = None,
    base_quat: Sequence[float] | None = None,
    base_rpy: Sequence[float] | None = None,
    floor: bool = True,
    decompose: str = "auto",
    coacd_options: dict[str, Any] | None = None,
) -> mujoco.MjModel:
    """``SCENES["file"]``: the obstacles of the MJCF ``scene_file`` around ``arm``.

    ``build_arm_model(arm, "file", scene_file=PATH, base_pos=…, base_quat=… | base_rpy=…,
    floor=True, decompose="auto", coacd_options=None)``; see :func:`load_scene_file`.
    """
    if scene_file is None:
        raise ValueError("scene='file' needs scene_file=PATH (an MJCF file of the cell)")
    scene = load_scene_file(scene_file, base_pos=base_pos, base_quat=base_quat,
                            base_rpy=base_rpy, decompose=decompose,
                            coacd_options=coacd_options)
    add_scene_file(spec, scene, floor=floor)
    try:
        return compile_spec(spec, collision_shapes=tree.collision_shapes)
    except ValueError as exc:
        raise SceneFileError(scene.path, f"merged with arm {arm.name!r}, MuJoCo cannot "
                             f"compile it: {_one_line(exc)}") from None
