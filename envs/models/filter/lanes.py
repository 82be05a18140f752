"""Lanes: 16 samples bounded in one call of a small C kernel (``lanes.c``).

The scalar kernels bound one sample at a time. A path check keeps up to 16 paths in
flight instead, each with the scalar loop's raked search, started from several intervals
at once when its scene has few paths (``kernels._lane_paths``): each round, the next
interval of every path in turn fills the lanes, and the kernel's ``lane_block`` bounds
their middle samples at once, returning per lane a free step (every pair farther than its
margin within it), "in contact" (a witness: inner shapes closer than the pair's contact
distance, as the scalar witnesses prove it) or "not proven"; a sample the lanes do not
prove goes to the scalar kernel, witnesses and MuJoCo exactly as before. The rounds run
in C too (``lane_paths``), which hands each such sample back to the numba loop that
called it and goes on from there. A configuration check of two or more rows fills the
lanes with rows (``kernels._lane_configurations``). The lanes prove only what the scalar
kernels would, so every verdict and first colliding sample stays MuJoCo's.

The lanes' bounds hold each moving geom's container in spheres: on its axis, or about
the cells of a box (:func:`covers`): a cover sphere's centre measured to the partner's
container, less its radius, bounds the pair's distance from below; points on the moving
geom's inner segment (:func:`witness_points`), measured to the partner's inner shape,
bound it from above. A box's or a cylinder's distance to a half-space is measured exactly
(its height over the plane less its extent along the normal), and a moving box's to any
bounded partner also by their separation along the two shapes' face normals, where a
cell's sphere reaches past the face (a carriage beside its rails).
They are looser than the scalar kernel's (which measure the containers themselves and
use each sample's local speeds), and much
cheaper: structure-of-arrays, every inner loop one run of SIMD instructions over the
lanes (``docs/models.md`` has the measurements, and why C rather than numba).

The C source is compiled on first use with the system's C compiler (``cc``, or ``CC``)
into the kernels' cache directory (``envs.jit``), keyed by a hash of the source, the
flags and the processor's features, as numba caches its kernels; ``make`` does it ahead.
Without a compiler the filter runs its scalar kernels only (same verdicts, slower), and
says so once. A model whose moving geoms the covers cannot hold (a moving plane, a geom of
an unknown kind) runs the scalar kernels too.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import math
import os
import platform
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

import mujoco
import numpy as np

from ...jit import cache_directory
from .layout import BOX, CAPSULE, CYLINDER, SPHERE, CompiledScene

#: Samples per call (the C kernel's ``L``).
LANES = 16
#: lanes.c's ``Paths`` (``lane_paths``' state, every field an int64): its size, what
#: ``lane_paths`` returns when it hands a sample back, and the fields the caller reads:
#: the scene in flight, the lane handed back, then per place its path and per lane its
#: place and interval (arrays of ``LANES`` from ``P_PATH`` on: path, grid, found, head,
#: tail, owner, loaded, lo, hi, mid).
PATHS_FIELDS, PATHS_SCALAR = 26 + 10 * LANES, 1
P_CURRENT, P_LANE, P_PATH = 20, 23, 26
P_OWNER, P_LO, P_HI, P_MID = (P_PATH + k * LANES for k in (5, 7, 8, 9))
#: A cover sphere's centres lie at most this fraction of the geom's radius apart (half
#: spacing): a capsule or cylinder of radius r is held by spheres of radius ≤ 1.118·r.
COVER_SPACING = 0.5
#: The most spheres that hold a box (:func:`box_cells`): its covers are looser than a
#: capsule's (a cell's sphere reaches past the faces), denser ones cost more per sample
#: than the near misses they would prove (docs/models.md, "Boxes and half-spaces").
BOX_COVERS = 16

_SOURCE = Path(__file__).with_name("lanes.c")
#: ``-fno-math-errno``: ``sqrt`` is one instruction. ``-fno-trapping-math``: GCC otherwise
#: keeps a branch for every ``MAX(x - s, 0.0)`` (it may not compute ``x - s`` where a
#: trap could tell), and the loops of the box and cylinder distances stay scalar. Neither
#: changes a computed value (no reassociation, no contraction beyond the default).
_FLAGS = ("-O3", "-march=native", "-fno-math-errno", "-fno-trapping-math", "-shared", "-fPIC")


def covers(scene: CompiledScene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spheres that hold each moving slot's container, in its body's frame: (start (S+1,),
    centres (C, 3), radii (C,)); slot s owns rows ``start[s]:start[s + 1]``, none for a
    static slot or one whose kind has no cover here (a moving plane, an unbounded geom).

    A capsule of radius r and half-length h: m = ⌈h/(``COVER_SPACING``·r)⌉ spheres of
    radius √(r² + (h/m)²) centred at −h + (2i + 1)·h/m on its axis hold its cylinder part
    (each the slab of height 2h/m around its centre), and a sphere of radius r at each end
    its caps; a cylinder the same without the caps; a sphere itself; a box (a mesh's box)
    the spheres about the cells of :func:`box_cells`, each through its cell's corners.
    Every centre lies within the slot's bounding radius of its centre and every radius is
    at most that radius, as the kernel's rounding allowance assumes (docs/models.md,
    "Single precision"). The radii carry a relative 1e-12 (and 1e-12 m) for rounding."""
    start, centres, radii = [0], [], []
    for s in range(len(scene.slot_type)):
        rows: list[tuple[tuple[float, float, float], float]] = []  # (centre, radius)
        kind, size = int(scene.slot_type[s]), scene.slot_size[0, s]
        if not scene.slot_static[s]:
            r, h = float(size[0]), float(size[1])
            if kind == SPHERE:
                rows = [((0.0, 0.0, 0.0), r)]
            elif kind in (CAPSULE, CYLINDER):
                m = max(1, math.ceil(h / (COVER_SPACING * r))) if h > 0.0 else 1
                half = h / m
                rows = [((0.0, 0.0, -h + half * (2 * i + 1)), math.hypot(r, half))
                        for i in range(m)]
                if kind == CAPSULE:
                    rows += [((0.0, 0.0, -h), r), ((0.0, 0.0, h), r)]
            elif kind == BOX:
                rows = box_cells(size, float(scene.slot_radius[0, s]))
        pos, rot = scene.slot_pos[0, s], scene.slot_rot[0, s]
        for offset, radius in rows:
            centres.append(pos + rot @ np.array(offset))
            radii.append(radius * (1.0 + 1e-12) + 1e-12)
        start.append(len(centres))
    return (np.array(start, dtype=np.int64), np.array(centres, dtype=np.float64).reshape(-1, 3),
            np.array(radii, dtype=np.float64))


def box_cells(half: np.ndarray, bounding: float = math.inf
              ) -> list[tuple[tuple[float, float, float], float]]:
    """The cover spheres of a box of half-sizes ``half`` (its frame): the box cut into
    n₀ × n₁ × n₂ equal cells, at most ``BOX_COVERS`` of them, each held by the sphere
    about its centre through its corners. Of the cuts whose centres and radii stay within
    ``bounding`` of the box's centre, the one whose spheres reach least beyond the box:
    a sphere of radius ρ = |c| about a cell of half-sizes c reaches ρ − min(c) beyond a
    face it lies on; ties go to fewer cells. Where no cut stays within (an ellipsoid's
    box, whose bounding radius is the ellipsoid's), the sphere of radius ``bounding``
    about the centre."""
    sizes = [float(x) for x in half]
    best: tuple[tuple[float, int], tuple[int, int, int]] | None = None
    for n0 in range(1, BOX_COVERS + 1):
        for n1 in range(1, BOX_COVERS // n0 + 1):
            for n2 in range(1, BOX_COVERS // (n0 * n1) + 1):
                cuts = (n0, n1, n2)
                cell = [x / n for x, n in zip(sizes, cuts, strict=True)]
                radius = math.sqrt(sum(c * c for c in cell))
                corner = math.sqrt(sum((x - c) ** 2 for x, c in zip(sizes, cell, strict=True)))
                if radius > bounding or corner > bounding:
                    continue
                key = (radius - min(cell), n0 * n1 * n2)
                if best is None or key < best[0]:
                    best = (key, cuts)
    if best is None:
        return [((0.0, 0.0, 0.0), bounding)]
    cuts = best[1]
    cell = [x / n for x, n in zip(sizes, cuts, strict=True)]
    radius = math.sqrt(sum(c * c for c in cell))
    axes = [[-x + c * (2 * i + 1) for i in range(n)]
            for x, c, n in zip(sizes, cell, cuts, strict=True)]
    return [((x, y, z), radius) for x in axes[0] for y in axes[1] for z in axes[2]]


def witness_points(scene: CompiledScene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points on each moving slot's inner segment, from which the lanes prove contacts:
    (start (S+1,), offsets along the slot's axis (W,), spacing per slot (S,)); slot s owns
    ``offsets[start[s]:start[s + 1]]``, none where its inner shape is not a sphere or a
    capsule (a box, none) or the slot is static.

    A capsule inner shape of radius r and half-length h: n = ⌈2h/r⌉ + 1 points from −h to
    h (both ends, which the skewer rule reads), evenly spaced ≤ r apart; a sphere its
    centre. Balls of radius r about them lie inside the inner shape."""
    start, spacing = [0], np.zeros(len(scene.slot_type))
    offsets: list[float] = []
    for s in range(len(scene.slot_type)):
        kind, size = int(scene.slot_inner[0, s]), scene.slot_inner_size[0, s]
        if not scene.slot_static[s] and kind in (SPHERE, CAPSULE):
            r, h = float(size[0]), float(size[1]) if kind == CAPSULE else 0.0
            n = math.ceil(2.0 * h / r) + 1 if h > 0.0 else 1
            offsets += np.linspace(-h, h, n).tolist() if n > 1 else [0.0]
            spacing[s] = 2.0 * h / (n - 1) if n > 1 else 0.0
        start.append(len(offsets))
    return (np.array(start, dtype=np.int64), np.array(offsets, dtype=np.float64),
            spacing)


def _processor() -> str:
    """What ``-march=native`` depends on: the machine and its CPU flags."""
    flags = ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            flags = next((line for line in info if line.startswith("flags")), "")
    except OSError:
        pass
    return platform.machine() + flags


@functools.cache
def library() -> ctypes.CDLL | None:
    """The compiled lane kernel (built on first use, then loaded from the cache), or None
    where no C compiler or cache directory is available."""
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    directory = cache_directory()
    if compiler is None or directory is None or not _SOURCE.exists():
        warnings.warn(f"no C compiler, cache directory or {_SOURCE.name}: the collision "
                      "filter runs without its lanes (same verdicts, slower)", RuntimeWarning,
                      stacklevel=2)
        return None
    digest = hashlib.sha256(_SOURCE.read_bytes() + repr((compiler, _FLAGS, _processor()))
                            .encode()).hexdigest()[:16]
    target = Path(directory) / f"lanes-{digest}.so"
    if not target.exists():
        with tempfile.TemporaryDirectory(dir=directory) as scratch:
            built = Path(scratch) / target.name
            try:
                result = subprocess.run([compiler, *_FLAGS, str(_SOURCE), "-o", str(built),
                                         "-lm"], capture_output=True, text=True, check=False)
                problem = result.stderr.strip()[:500] if result.returncode else ""
            except OSError as error:
                problem = str(error)
            if problem or not built.exists():
                warnings.warn(f"the collision filter's lanes did not compile ({compiler}): "
                              f"{problem}; running without them", RuntimeWarning, stacklevel=2)
                return None
            os.replace(built, target)  # atomic: parallel processes may build it too
    lib = ctypes.CDLL(str(target))
    expected = _paths_layout()
    layout = np.zeros(len(expected), dtype=np.int64)
    lib.lane_paths_layout(ctypes.c_void_p(layout.ctypes.data))
    if tuple(layout.tolist()) != expected:
        raise RuntimeError(f"lanes.c lays its Paths out as {tuple(layout.tolist())}, the "
                           f"kernels read it as {expected}: the two must agree")
    return lib


def _paths_layout() -> tuple[int, ...]:
    """``Paths`` as the kernels read it, in the order of lanes.c's ``lane_paths_layout``:
    the offsets of the 18 fields they set (in struct order), of the fields they read, its
    size, ``PATHS_SCALAR``."""
    return (*range(18), P_CURRENT, P_LANE, P_PATH, P_OWNER, P_LO, P_HI, P_MID, PATHS_FIELDS,
            PATHS_SCALAR)


_POINTERS = ("body_parent body_pos body_rot body_jntadr body_jntnum body_flags jnt_type "
             "jnt_qposadr jnt_pos jnt_axis qpos0 body_xpos body_xmat slot_body slot_static "
             "slot_pos slot_rot slot_type slot_size pair_a pair_b pair_margin pair_reach "
             "pair_kind pair_fixed cover_start cover_pos cover_radius slot_turned slot_inner "
             "slot_inner_size pair_contact pair_skewer witness_start witness_offset "
             "witness_spacing slot_radius pair_spheres").split()


class _Scene(ctypes.Structure):
    """``Scene`` of lanes.c: counts, then the arrays' addresses."""

    _fields_ = [("nbody", ctypes.c_int64), ("nslot", ctypes.c_int64),
                ("npair", ctypes.c_int64)] + [(name, ctypes.c_void_p) for name in _POINTERS]


class LaneScene:
    """One scene of a filter as the lane kernel reads it: the ``Scene`` struct, pointing
    at ``scene``'s arrays (its per-scene fields' only row: a filter's own, or its row of a
    stack's, so that refreshed clutter is read in place) and at the covers. ``address`` is
    0 where the lanes cannot serve the model (:func:`usable`) or were not built."""

    def __init__(self, scene: CompiledScene, spheres_only: np.ndarray | None = None) -> None:
        """``spheres_only`` (P,) bool: pairs the lanes prove free by their bounding spheres
        alone (:func:`primitive_box_pairs`; none if not given)."""
        self._arrays: list[np.ndarray] = []  # kept alive while the struct points at them
        self.address = self.function = self.paths_function = 0
        lib = library()
        self.covers = covers(scene)
        self.witnesses = witness_points(scene)
        #: Doubles of a call's work array.
        self.work_doubles = work_size(scene, len(self.covers[2]))
        if lib is None or not usable(scene, self.covers[0]):
            return
        turned = np.zeros(len(scene.slot_type), dtype=np.uint8)
        turned[scene.pair_b[~scene.slot_static[scene.pair_b]]] = 1
        fields = {name: getattr(scene, name) for name in _POINTERS if hasattr(scene, name)}
        fields["slot_static"] = scene.slot_static.astype(np.uint8)
        fields["pair_skewer"] = scene.pair_skewer.astype(np.uint8)
        fields["pair_spheres"] = (np.zeros(len(scene.pair_a), dtype=np.uint8)
                                  if spheres_only is None else spheres_only.astype(np.uint8))
        fields.update(cover_start=self.covers[0], cover_pos=self.covers[1],
                      cover_radius=self.covers[2], slot_turned=turned)
        fields.update(zip(("witness_start", "witness_offset", "witness_spacing"),
                          self.witnesses, strict=True))
        struct = _Scene(nbody=len(scene.body_parent), nslot=len(scene.slot_type),
                        npair=len(scene.pair_a))
        for name in _POINTERS:
            array = fields[name]
            if array.ndim and array.shape[0] == 1 and name in _ROW:
                array = array[0]  # the scene's row
            if not array.flags.c_contiguous:
                raise ValueError(f"lane scene: {name} is not contiguous")
            self._arrays.append(array)
            setattr(struct, name, array.ctypes.data)
        self._struct = struct
        self._call = lib.lane_block
        self._call.argtypes, self._call.restype = [ctypes.c_void_p, ctypes.c_void_p], None
        self.address = ctypes.addressof(struct)
        self.function = ctypes.cast(lib.lane_block, ctypes.c_void_p).value or 0
        #: The path search over this kernel (``kernels._lane_paths`` calls it).
        self.paths_function = ctypes.cast(lib.lane_paths, ctypes.c_void_p).value or 0
        self._sizes = (len(scene.body_parent), len(scene.pair_a), len(scene.qpos0))

    def bound(self, start: np.ndarray, change: np.ndarray, t: np.ndarray, cap: np.ndarray,
              rates: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One call of the kernel from Python (tests, benchmarks): ``start`` and ``change``
        (LANES, nq) full qpos rows, ``t`` and ``cap`` (LANES,), ``rates`` (LANES, pairs).
        Returns the steps (LANES,): per lane a free step, −1 (not proven free) or −2
        (proven in contact); and the bodies' frames per lane: positions (nbody, 3, LANES)
        and rotations (nbody, 3, 3, LANES), the kernel's for every moving body (a static
        body's frame is the model's, in its rows only where a moving child needs it)."""
        if not self.address:
            raise ValueError("this filter has no lanes (LaneScene.address is 0)")
        nbody, npair, nq = self._sizes
        inputs = [np.ascontiguousarray(np.asarray(a, dtype=np.float64).T)
                  for a in (start, change)]
        inputs += [np.ascontiguousarray(t, dtype=np.float64),
                   np.ascontiguousarray(cap, dtype=np.float64),
                   np.ascontiguousarray(np.asarray(rates, dtype=np.float64).T)]
        shapes = [(nq, LANES), (nq, LANES), (LANES,), (LANES,), (npair, LANES)]
        for array, shape in zip(inputs, shapes, strict=True):
            if array.shape != shape:
                raise ValueError(f"lane inputs: expected shape {shape}, got {array.shape}")
        steps, work = np.zeros(LANES), np.zeros(self.work_doubles)
        block = np.array([a.ctypes.data for a in (*inputs, steps, work)] + [LANES],
                         dtype=np.uint64)
        self._call(self.address, block.ctypes.data)
        frames = work[: LANES * 12 * nbody]
        return (steps, frames[: LANES * 3 * nbody].reshape(nbody, 3, LANES),
                frames[LANES * 3 * nbody :].reshape(nbody, 3, 3, LANES))


#: The struct's fields that are per-scene arrays (a leading scene axis of length 1).
_ROW = frozenset({"slot_pos", "slot_rot", "slot_size", "pair_fixed", "pair_reach",
                  "pair_kind", "slot_inner", "slot_inner_size", "slot_radius"})


def primitive_box_pairs(model: mujoco.MjModel, scene: CompiledScene) -> np.ndarray:
    """(P,) bool: the pair is two primitive boxes of ``model``. MuJoCo's box–box collider
    misses some contacts inside the margin and reports some outside it (docs/models.md,
    "Witnesses"), so no distance bound, however true, proves such a pair free as MuJoCo
    decides it: the lanes prove it free by the bounding spheres alone, which is MuJoCo's
    own broad phase. The models ``envs.models`` builds have none (their boxes are meshes,
    the clutter's primitive boxes meet no other box)."""
    boxes = model.geom_type[scene.slot_geom] == mujoco.mjtGeom.mjGEOM_BOX
    return boxes[scene.pair_a] & boxes[scene.pair_b]


def usable(scene: CompiledScene, cover_start: np.ndarray) -> bool:
    """The lanes serve ``scene`` when every moving slot that is some pair's first (the one
    they measure by its covers) has covers."""
    owned = np.diff(cover_start)
    return bool(np.all(owned[np.unique(scene.pair_a)] > 0)) if len(scene.pair_a) else False


def work_size(scene: CompiledScene, n_covers: int) -> int:
    """Doubles of a call's work array: body frames, slot centres and their largest
    coordinates in double precision, then slot centres, slot frames and cover centres in
    single precision (two a double)."""
    singles = LANES * (12 * len(scene.slot_type) + 3 * n_covers)
    return LANES * (12 * len(scene.body_parent) + 4 * len(scene.slot_type)) + (singles + 1) // 2
