"""Collision checks of configurations and of linear joint-space paths.

A path between two configurations is ``q(t) = q0 + t·(q1 − q0)``, t ∈ [0, 1], sampled at
``n + 1`` evenly spaced points, both ends included. The checker reports arm–obstacle,
self (non-excluded link pairs) and arm–arm contacts alike: any contact between two
collision geoms counts.

Resolution, and why sampling is safe
------------------------------------
A point p rigidly attached downstream of joint i moves, when the joints move at rates q̇,
with speed |ṗ| ≤ Σ_hinge R_i·|q̇_i| + Σ_slide |q̇_j|, where R_i bounds the distance from
hinge i's axis to any collision-geom point downstream of it over *all* configurations
(``CollisionChecker.lever``, the largest over bodies of :func:`body_lever_arms`, computes
it from the compiled model: body offsets, each geom's bounding sphere ``geom_rbound``, plus
the full stroke of every slide in between).
Integrating along the path, between two consecutive samples every geom point moves at
most

    D/n,   D = Σ_hinge R_i·|Δq_i| + Σ_slide |Δq_j|   (Δq = q1 − q0).

The checker takes a Cartesian ``resolution`` δ (default 10 mm), uses n = ⌈D/δ⌉ and
inflates every collision geom by a contact margin δ/2 (MuJoCo adds the two geoms'
margins, so a pair counts as colliding when it is closer than δ). If no sample reports a
contact, every pair is at distance ≥ δ at every sample; between samples a geom moves at
most δ, so an arm–obstacle distance stays ≥ δ/2 > 0 and an arm–arm or self distance
(both geoms move) stays ≥ 0: the whole continuous path is free of penetration, not only
the samples. The price is conservatism: configurations closer than δ to something count
as colliding.

For scale, the anthropomorphic arm's R (with the tool) is ~2.5 m for φ1, so one degree of
φ1 alone moves the tool tip ~44 mm. A "1° per joint" rule would therefore let a geom jump
through a 30 mm obstacle; the Cartesian rule puts ~600 samples on the paper's 1.1 → 2.1
transfer (δ = 10 mm), and a 20 mm rod is always caught (see the tests).

Conservative advancement (the loop backend)
-------------------------------------------
Most samples of a path lie far from everything. The loop backend visits the same grid
t_i = i/n but skips samples it can prove free. The distance of a geom pair changes along
the path at most at rate L = Σ_j R_j,b·|Δq_j| over the joints that move its two bodies
relative to each other (per-body lever arms, :func:`body_lever_arms`; joints that move
both bodies turn them rigidly together and drop out). At a checked sample every pair that
``mj_collision`` may test (:func:`candidate_pairs`) gets a lower bound on its distance d:
its bounding spheres' gap (a half-space for a plane), replaced by the exact
``mj_geomDistance`` for the pairs whose bound would limit the step. The next
⌊min (d − δ)/L · n⌋ samples keep every pair farther than δ, so they would pass the δ check
and are skipped; a sample with a pair closer than δ is decided by ``mj_collision`` itself.
The outcome and the first colliding sample therefore equal the flat check's (tested on
random scenes of every arm); only the work shrinks (``benchmarks/collision_throughput.py``).

Two MuJoCo behaviours broke the δ guarantee itself and are avoided (both found by
comparing ``mj_collision`` with ``mj_geomDistance`` along Anthropomorphic-v0 paths): the
box–box collider misses pairs inside their margin in some orientations
(google-deepmind/mujoco#2471; a gripper 8.8 mm from an obstacle went unreported), so
collision boxes are built as convex meshes (``envs.models.builders.compile_spec``); and
the body-level midphase dropped a gripper–floor pair 6 mm apart when the margins are set
on the compiled model, so the checker disables the midphase (moving bodies carry ≤ 3
collision geoms).

Backends (identical results: tested equal, and asserted by the benchmark)
------------------------------------------------------------------------
``"compiled"`` (the default; ``"auto"`` picks it) the filter of :mod:`envs.models.filter`:
             numba kernels bound every candidate pair from geometry read off the model and
             prove most samples free; every other sample goes to ``mj_kinematics`` +
             ``mj_collision``, called from the kernel. Same verdicts and first colliding
             samples as the loop, several tens of times faster on paths. Verdict-only
             calls (:meth:`CollisionChecker.paths_collide`) stop at any contact.
``"loop"``   ``mj_kinematics`` + ``mj_collision`` on one reused ``MjData``; path checks
             advance conservatively (above) and stop at each path's first contact. The
             exact reference the compiled backend is tested against.
``"batch"``  ``mujoco.batch.Batch``: C thread pool, GIL released, every grid sample. Its
             finest stage, ``mjSTAGE_POS``, also computes inertia, its factorisation and
             the contact constraints, ~1.3× the work of kinematics + collision per
             configuration.

The grid is one definition for every backend: n = max(⌈D/δ − 10⁻¹²⌉, 1) with D summed in
joint order (``compiled.path_steps``), so a path has the same samples alone or in a batch.
Contacts of a colliding sample are read back with the loop's ``MjData``. The checker holds
private copies of the model (with the margins), their ``MjData`` and the lazily built
batch; results depend only on the inputs.
"""

from __future__ import annotations

import copy
import itertools
import math
from dataclasses import dataclass

import mujoco
import mujoco.batch
import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics.compiled import writable

from .filter import DISTANCE_TOLERANCE, CompiledFilter, path_steps
from .filter.kernels import BY_MUJOCO
from .filter.layout import _GEOM_PLANE as PLANE  # an int: numpy compares mujoco's enum per element

#: Default Cartesian resolution δ (m): largest displacement of any geom point between
#: samples, and the clearance below which two geoms count as colliding.
DEFAULT_RESOLUTION = 0.01
#: ``CollisionChecker`` backends (module docstring); "auto" is "compiled".
BACKENDS = ("auto", "compiled", "batch", "loop")
#: Paths the loop backend advances side by side.
LOOP_CHUNK = 256


@dataclass(frozen=True)
class Contact:
    """One contact of a colliding configuration (geom and body names, distance in m).

    ``distance`` is MuJoCo's signed distance (negative: penetration); a value in
    [0, resolution) is a near miss caught by the clearance margin.
    """

    geom1: str
    geom2: str
    body1: str
    body2: str
    distance: float


@dataclass(frozen=True)
class PathResult:
    """Outcome of one path check."""

    collides: bool
    #: t ∈ [0, 1] of the first colliding sample, NaN for a free path.
    first_fraction: float
    #: Contacts at the first colliding sample (empty for a free path).
    contacts: tuple[Contact, ...]
    n_samples: int

    @property
    def pairs(self) -> tuple[tuple[str, str], ...]:
        return tuple(sorted({(c.geom1, c.geom2) for c in self.contacts}))

    def __eq__(self, other: object) -> bool:
        # Two free paths are equal although NaN != NaN (the dataclass default compares
        # first_fraction with ==).
        if not isinstance(other, PathResult):
            return NotImplemented
        same_fraction = self.first_fraction == other.first_fraction or (
            math.isnan(self.first_fraction) and math.isnan(other.first_fraction))
        return (same_fraction and self.collides == other.collides
                and self.contacts == other.contacts and self.n_samples == other.n_samples)

    def __hash__(self) -> int:
        fraction = None if math.isnan(self.first_fraction) else self.first_fraction
        return hash((self.collides, fraction, self.contacts, self.n_samples))


def body_lever_arms(model: mujoco.MjModel, dof: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-body lever arms of the first ``dof`` joints: ``levers`` (nbody, dof) bounds how
    fast any collision-geom point of body b moves per unit speed of joint j (m/rad for a
    hinge, over all configurations; 1 for a slide; 0 unless j moves b), and ``moves``
    (nbody, dof) is 1 where joint j moves body b."""
    hinge_or_slide = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
    if not np.isin(model.jnt_type, hinge_or_slide).all():
        raise ValueError("path checks support hinge and slide joints only")
    collide = (model.geom_contype | model.geom_conaffinity) != 0
    own = np.zeros(model.nbody)  # body origin to its farthest collision-geom point
    for g in np.flatnonzero(collide):
        b = model.geom_bodyid[g]
        own[b] = max(own[b], np.linalg.norm(model.geom_pos[g]) + model.geom_rbound[g])
    levers, moves = np.zeros((model.nbody, dof)), np.zeros((model.nbody, dof))
    for b in range(1, model.nbody):
        reach, body = own[b], b  # reach: bound on |point − origin of ``body``|
        while body != 0:
            first = model.body_jntadr[body]
            joints = range(first, first + model.body_jntnum[body])
            stroke = 0.0
            for j in joints:
                slide = model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE
                if j < dof:
                    moves[b, j] = 1.0
                    levers[b, j] = 1.0 if slide else np.linalg.norm(model.jnt_pos[j]) + reach
                if slide:
                    stroke += np.max(np.abs(model.jnt_range[j])) if model.jnt_limited[j] else np.inf
            reach += np.linalg.norm(model.body_pos[body]) + stroke
            body = model.body_parentid[body]
    return levers, moves


def candidate_pairs(model: mujoco.MjModel) -> np.ndarray:
    """(P, 2) geom pairs ``mj_collision`` may test, a plane always first: collision geoms
    with compatible contype/conaffinity on different, non-welded bodies, minus explicit
    excludes and (unless disabled) parent–child pairs, the filters MuJoCo applies."""
    weld = model.body_weldid
    weld_parent = weld[model.body_parentid[weld]]
    filter_parent = not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
    excluded = set(model.exclude_signature.tolist())
    geoms = np.flatnonzero((model.geom_contype | model.geom_conaffinity) != 0)
    pairs = []
    for g1, g2 in itertools.combinations(geoms, 2):
        b1, b2 = model.geom_bodyid[g1], model.geom_bodyid[g2]
        w1, w2 = weld[b1], weld[b2]
        if w1 == w2:
            continue
        if filter_parent and w1 and w2 and (w1 == weld_parent[b2] or w2 == weld_parent[b1]):
            continue
        if ((min(b1, b2) << 16) + max(b1, b2)) in excluded:
            continue
        if not (model.geom_contype[g1] & model.geom_conaffinity[g2]
                or model.geom_contype[g2] & model.geom_conaffinity[g1]):
            continue
        plane2 = model.geom_type[g2] == PLANE
        pairs.append((g2, g1) if plane2 else (g1, g2))
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


class CollisionChecker:
    """Collision checks on one compiled model.

    ``dof``: the number of leading qpos entries the configurations give (default all);
    the rest stay at ``qpos0``. ``resolution`` δ (m): see the module docstring.
    ``pad=False`` checks exact contact (margin 0) instead of clearance δ; path checks then
    only guarantee the samples. ``nthread`` threads for the batch (0: all CPUs), ``chunk``
    configurations per batch call. ``backend``: see the module docstring.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        dof: int | None = None,
        resolution: float = DEFAULT_RESOLUTION,
        pad: bool = True,
        nthread: int = 0,
        chunk: int = 1024,
        backend: str = "auto",
    ) -> None:
        if not resolution > 0.0:
            raise ValueError("resolution must be positive")
        self.model = copy.copy(model)  # private: the margins below must not leak
        self.dof = model.nq if dof is None else int(dof)
        if not 0 < self.dof <= model.nq or model.nq != model.nv:
            raise ValueError("dof must select leading qpos entries of hinge/slide joints")
        self.resolution = float(resolution)
        self.pad = pad
        collide = (self.model.geom_contype | self.model.geom_conaffinity) != 0
        self.model.geom_margin[collide] = 0.5 * resolution if pad else 0.0
        self.model.geom_gap[collide] = 0.0
        self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_MIDPHASE
        self._data = mujoco.MjData(self.model)
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(map(repr, BACKENDS))}")
        if backend == "auto":
            backend = "compiled"
        self.backend = backend
        self._nthread = nthread
        self._chunk = int(chunk)
        self._batch: mujoco.batch.Batch | None = None
        # Hinges and slides only: joint j is qpos[j].
        levers, moves = body_lever_arms(self.model, self.model.njnt)
        self.lever = levers.max(axis=0)[: self.dof]
        self._body_levers, self._body_moves = levers[:, : self.dof], moves[:, : self.dof]
        pairs = candidate_pairs(self.model)
        # Pairs with a plane last (their bound is a half-space, the others' a sphere gap).
        plane = self.model.geom_type[pairs] == PLANE
        order = np.argsort(plane[:, 0], kind="stable")
        self._pairs, plane = pairs[order], plane[order]
        self._plane_pairs = plane[:, 0]
        self._pair_bodies = self.model.geom_bodyid[self._pairs]
        self._radius_sum = np.where(plane, 0.0, self.model.geom_rbound[self._pairs]).sum(axis=1)
        # The loop backend's bounds: per pair its second geom's centre less its first's; a
        # plane's z axis (row-major xmat) dotted with that is the height above it.
        self._spheres = int(np.count_nonzero(~self._plane_pairs))
        self._normal_columns = (self._pairs[self._spheres:, :1] * 9
                                + np.arange(2, 9, 3)).ravel()
        self._first_ids, self._second_ids = self._pairs[:, 0].tolist(), self._pairs[:, 1].tolist()
        self._body_names: tuple[str, ...] | None = None  # by id, made when first asked
        self._filter: CompiledFilter | None = None
        if backend == "compiled":
            self._filter = CompiledFilter(self.model, self._data, self.dof, self._pairs)

    def refresh_static(self, geoms: np.ndarray | None = None) -> None:
        """Follow static geoms whose places or sizes were changed on ``self.model`` (the
        per-episode clutter, ``envs.models.scenes.ClutterSlots``; ``geoms``: their ids,
        default all): every backend's cached view of them is rebuilt. Candidate pairs and
        lever arms do not depend on them."""
        if self._filter is not None:
            self._filter.refresh_static(geoms)
            return
        plane = self.model.geom_type[self._pairs] == PLANE
        self._radius_sum = np.where(plane, 0.0, self.model.geom_rbound[self._pairs]).sum(axis=1)
        self._batch = None

    def _compiled(self) -> CompiledFilter:
        """The compiled backend's filter."""
        assert self._filter is not None  # __init__ builds it for the compiled backend
        return self._filter

    # ------------------------------------------------------------------ configurations
    def _full_qpos(self, q: np.ndarray) -> np.ndarray:
        full = np.broadcast_to(self.model.qpos0, (len(q), self.model.nq)).copy()
        full[:, : self.dof] = q
        return full

    def _ensure_batch(self) -> mujoco.batch.Batch:
        if self._batch is None:
            self._batch = mujoco.batch.Batch(self.model, self._chunk, self._nthread)
            # Bind before the first call: bound outputs are filled by every later call.
            self._qpos = self._batch.bind("qpos")
            self._ncon = self._batch.bind("ncon")
        return self._batch

    def _configurations(self, q: ArrayLike) -> np.ndarray:
        """``q`` (…, dof) as float rows, ``ValueError`` for a wrong last axis or NaN/inf."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape[-1:] != (self.dof,):
            raise ValueError(f"q must have shape (..., {self.dof}), got {q.shape}")
        if not np.all(np.isfinite(q)):
            raise ValueError("q contains NaN or inf")
        return q

    def n_contacts(self, q: ArrayLike) -> np.ndarray:
        """Number of contacts (within the margin) for configurations ``q`` (…, dof)."""
        q = self._configurations(q)
        flat = q.reshape(-1, self.dof)
        if self.backend == "loop":
            return self._n_contacts_loop(flat).reshape(q.shape[:-1])
        if self.backend == "compiled":
            return self._compiled().contacts(np.ascontiguousarray(flat)).reshape(q.shape[:-1])
        out = np.empty(len(flat), dtype=np.int64)
        batch = self._ensure_batch()
        for start in range(0, len(flat), self._chunk):
            rows = self._full_qpos(flat[start : start + self._chunk])
            n = len(rows)
            self._qpos[:n] = rows
            ids = None if n == self._chunk else np.arange(n)
            batch.forward(ids, stage=mujoco.mjtStage.mjSTAGE_POS)
            out[start : start + n] = self._ncon[:n]
        return out.reshape(q.shape[:-1])

    def collides(self, q: ArrayLike) -> np.ndarray:
        """(…,) bool: configuration ``q`` (…, dof) has a contact (closer than δ if padded).
        The compiled backend takes a contact its inner shapes prove without counting it."""
        if self.backend == "compiled":
            q = self._configurations(q)
            flat = np.ascontiguousarray(q.reshape(-1, self.dof))
            return (self._compiled().collide(flat) > 0).reshape(q.shape[:-1])
        return self.n_contacts(q) > 0

    def collides_loop(self, q: ArrayLike) -> np.ndarray:
        """Same as :meth:`collides` with the plain loop, whatever the backend."""
        q = np.asarray(q, dtype=np.float64)
        return (self._n_contacts_loop(q.reshape(-1, self.dof)) > 0).reshape(q.shape[:-1])

    def _n_contacts_loop(self, flat: np.ndarray, stop_at_first: bool = False) -> np.ndarray:
        full = self._full_qpos(flat)
        model, data = self.model, self._data
        out = np.zeros(len(full), dtype=np.int64)
        for i, row in enumerate(full):
            data.qpos[:] = row
            mujoco.mj_kinematics(model, data)
            mujoco.mj_collision(model, data)
            out[i] = data.ncon
            if stop_at_first and data.ncon:
                break
        return out

    def contacts(self, q: ArrayLike) -> tuple[Contact, ...]:
        """The contacts of one configuration ``q`` (dof,), closest first."""
        model, data = self.model, self._collide_one(q)
        found = []
        for c in data.contact[: data.ncon]:
            g1, g2 = int(c.geom1), int(c.geom2)
            found.append(
                Contact(
                    model.geom(g1).name,
                    model.geom(g2).name,
                    model.body(model.geom_bodyid[g1]).name,
                    model.body(model.geom_bodyid[g2]).name,
                    float(c.dist),
                )
            )
        return tuple(sorted(found, key=lambda c: c.distance))

    def contact_bodies(self, q: ArrayLike) -> frozenset[str]:
        """The names of the bodies in contact at one configuration ``q`` (dof,): the bodies
        of :meth:`contacts`, read from MuJoCo's contact array at once."""
        model, data = self.model, self._collide_one(q)
        if self._body_names is None:
            self._body_names = tuple(model.body(b).name for b in range(model.nbody))
        bodies = model.geom_bodyid[data.contact.geom[: data.ncon]].ravel().tolist()
        return frozenset(self._body_names[b] for b in bodies)

    def _collide_one(self, q: ArrayLike) -> mujoco.MjData:
        """The checker's data with MuJoCo's contacts of one configuration ``q`` (dof,)."""
        data = self._data
        data.qpos[:] = self._full_qpos(np.asarray(q, dtype=np.float64)[None])[0]
        mujoco.mj_kinematics(self.model, data)
        mujoco.mj_collision(self.model, data)
        return data

    # ------------------------------------------------------------------------- paths
    def displacement_bound(self, q0: ArrayLike, q1: ArrayLike) -> np.ndarray:
        """(…,) D = Σ_j R_j |Δq_j|: largest distance (m) any geom point travels along the
        linear path (summed in joint order, as :meth:`n_steps` does)."""
        delta = np.abs(np.asarray(q1, dtype=np.float64) - np.asarray(q0, dtype=np.float64))
        return (delta * self.lever).sum(axis=-1)

    def n_steps(self, q0: ArrayLike, q1: ArrayLike) -> np.ndarray:
        """(…,) number of intervals n = ⌈D/δ⌉ (≥ 1) for the path q0 → q1: one definition
        (``compiled.path_steps``) for every backend and batch shape."""
        q0, q1 = self._ends(q0, q1)
        shape = np.broadcast_shapes(q0.shape, q1.shape)[:-1]
        start, end = np.broadcast_arrays(q0, q1)
        start = writable(np.ascontiguousarray(start.reshape(-1, self.dof)))
        end = writable(np.ascontiguousarray(end.reshape(-1, self.dof)))
        out = np.empty(len(end), dtype=np.int64)
        path_steps(start, end, self.lever, self.resolution, out)
        return out.reshape(shape)

    def path_samples(self, q0: ArrayLike, q1: ArrayLike) -> np.ndarray:
        """(n + 1, dof) samples q0 + (i/n)(q1 − q0) of the path q0 → q1 (both ends
        included), the grid every backend checks."""
        q0, q1 = self._ends(q0, q1)
        n = int(self.n_steps(q0, q1))
        return q0 + (np.arange(n + 1) / n)[:, None] * (q1 - q0)

    def check_path(self, q0: ArrayLike, q1: ArrayLike) -> PathResult:
        """Check the linear path q0 → q1 (each (dof,))."""
        q0, q1 = self._ends(q0, q1)
        collides, first, contacts, samples = self._check_paths_flat(q0[None], q1[None], True)
        return PathResult(bool(collides[0]), float(first[0]), contacts[0], int(samples[0]))

    def check_paths(self, q0: ArrayLike, q1: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Check many paths at once, ``q0`` and ``q1`` broadcast to (…, dof).

        Returns ``collides`` (…,) bool and ``first_fraction`` (…,) (NaN where free): the
        first colliding grid sample i/n of each path. Every path goes through one call,
        e.g. (K candidates × N waypoints) transfers.
        """
        q0, q1 = np.broadcast_arrays(*self._ends(q0, q1))
        shape = q0.shape[:-1]
        collides, first, _, _ = self._check_paths_flat(
            q0.reshape(-1, self.dof), q1.reshape(-1, self.dof), False
        )
        return collides.reshape(shape), first.reshape(shape)

    def paths_collide(self, q0: ArrayLike, q1: ArrayLike) -> np.ndarray:
        """(…,) bool: the verdicts of :meth:`check_paths` for ``q0``, ``q1`` broadcast to
        (…, dof), without the first colliding sample. The compiled backend stops a path at
        the first contact it finds, wherever on the path: the same verdict for less work.
        A single start (dof,) for many ends (M, dof) is the cheapest call (a step's K
        moves)."""
        q0, q1 = self._ends(q0, q1)
        if q0.ndim == 1 and q1.ndim == 2:
            return self.rows_paths_collide(q0[None], np.ascontiguousarray(q1))
        start, end = np.broadcast_arrays(q0, q1)
        shape = start.shape[:-1]
        start = np.ascontiguousarray(start.reshape(-1, self.dof))
        end = np.ascontiguousarray(end.reshape(-1, self.dof))
        return self.rows_paths_collide(start, end).reshape(shape)

    def rows_paths_collide(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """:meth:`paths_collide` for C-contiguous float64 rows already checked finite:
        ``start`` (M or 1, dof), ``end`` (M, dof). For callers that validated their input
        (``envs.moves``): no checks, one kernel call."""
        if self.backend != "compiled":
            start = np.broadcast_to(start, end.shape)
            return self._check_paths_flat(start, end, False)[0]
        start, end = writable(start), writable(end)
        steps = np.empty(len(end), dtype=np.int64)
        path_steps(start, end, self.lever, self.resolution, steps)
        return self._compiled().paths(start, end, steps, False) >= 0

    def rows_collide(self, q: np.ndarray) -> np.ndarray:
        """:meth:`collides` for C-contiguous float64 rows (M, dof) already checked finite."""
        if self.backend == "compiled":
            return self._compiled().collide(q) > 0
        return self.collides(q)

    def rows_collide_proved(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`rows_collide`, and per row whether a proof of the compiled filter decided
        it (bounds or inner shapes, each with its tolerance) rather than MuJoCo: a verdict
        that holds for any configuration placing every geom within far less than that
        tolerance of this one. Other backends prove nothing."""
        if self.backend == "compiled":
            out, how = self._compiled().collide_how(q)
            return out > 0, how != BY_MUJOCO
        return self.collides(q), np.zeros(len(q), dtype=bool)

    def first_free_rows(self, q: np.ndarray, need: int) -> np.ndarray:
        """Indices of the first ``need`` collision-free rows of ``q`` (C-contiguous float64
        (M, dof), checked finite), fewer if fewer are free: the rows after the ``need``-th
        free one are not checked (the compiled backend stops there)."""
        if self.backend == "compiled":
            return np.flatnonzero(self._compiled().collide(q, need) == 0)
        return np.flatnonzero(~self.collides(q))[:need]

    def _ends(self, q0: ArrayLike, q1: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Path ends as float arrays, ``ValueError`` for a wrong last axis or NaN/inf."""
        q0, q1 = np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64)
        for q in (q0, q1):
            if q.shape[-1:] != (self.dof,):
                raise ValueError(f"path ends must have shape (..., {self.dof}), got {q.shape}")
        if not (np.isfinite(q0).all() and np.isfinite(q1).all()):
            raise ValueError("path ends contain NaN or inf")
        return q0, q1

    def _check_paths_flat(
        self, q0: np.ndarray, q1: np.ndarray, want_contacts: bool
    ) -> tuple[np.ndarray, np.ndarray, list[tuple[Contact, ...]], np.ndarray]:
        steps = self.n_steps(q0, q1)
        counts = steps + 1
        collides = np.zeros(len(q0), dtype=bool)
        first = np.full(len(q0), np.nan)
        contacts: list[tuple[Contact, ...]] = [() for _ in range(len(q0))]
        if self.backend in ("compiled", "loop"):
            # Each path's first colliding grid index (−1 if free).
            index = (self._compiled().paths(np.ascontiguousarray(q0), np.ascontiguousarray(q1),
                                            steps, True)
                     if self.backend == "compiled" else self._first_hits_advancing(q0, q1, steps))
            for path in np.flatnonzero(index >= 0):
                collides[path] = True
                first[path] = index[path] / steps[path]
                if want_contacts:
                    sample = q0[path] + first[path] * (q1[path] - q0[path])
                    contacts[path] = self.contacts(sample)
            return collides, first, contacts, counts
        owner = np.repeat(np.arange(len(q0)), counts)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        t = (np.arange(counts.sum()) - starts[owner]) / steps[owner]
        samples = q0[owner] + t[:, None] * (q1[owner] - q0[owner])
        hit = self.collides(samples) if len(samples) else np.zeros(0, dtype=bool)
        hit_rows = np.flatnonzero(hit)
        if len(hit_rows):
            # The first hit of each path: hits are sorted, so np.unique's first index works.
            paths, index = np.unique(owner[hit_rows], return_index=True)
            rows = hit_rows[index]
            collides[paths] = True
            first[paths] = t[rows]
            if want_contacts:
                for path, row in zip(paths, rows, strict=True):
                    contacts[path] = self.contacts(samples[row])
        return collides, first, contacts, counts

    def _first_hits_advancing(self, q0: np.ndarray, q1: np.ndarray,
                              steps: np.ndarray) -> np.ndarray:
        """Per path q0 → q1 (M, dof) of ``steps`` (M,) grid steps: the index i of the first
        sample q0 + (i/n)(q1 − q0) closer than δ to a contact, −1 if none; samples the
        distances prove free are skipped (module docstring). The paths advance side by side,
        ``LOOP_CHUNK`` at a time: the bounds of every path standing at a sample are one numpy
        computation, the exact distances and ``mj_collision`` each path's own calls."""
        hits = np.full(len(q0), -1, dtype=np.int64)
        for start in range(0, len(q0), LOOP_CHUNK):
            rows = slice(start, start + LOOP_CHUNK)
            hits[rows] = self._advance_side_by_side(q0[rows], q1[rows], steps[rows])
        return hits

    def _advance_side_by_side(self, q0: np.ndarray, q1: np.ndarray,
                              n: np.ndarray) -> np.ndarray:
        """:meth:`_first_hits_advancing` of at most ``LOOP_CHUNK`` paths."""
        hits = np.full(len(q0), -1, dtype=np.int64)
        delta = q1 - q0
        weighted = self._body_levers[None] * np.abs(delta)[:, None, :]  # (M, nbody, dof)
        reach = weighted.sum(axis=2)
        shared = weighted @ self._body_moves.T  # motion of b1's points by b2's joints
        # Rate (per unit t) at which the distance of bodies b1, b2 can change: joints that
        # move both turn them rigidly together and drop out.
        rate = reach[:, :, None] + reach[:, None, :] - shared - shared.transpose(0, 2, 1)
        pair_rate = rate[:, self._pair_bodies[:, 0], self._pair_bodies[:, 1]]  # (M, npair)
        moving = pair_rate > 1e-12
        # Nothing moves relative to anything: one sample decides.
        still = np.flatnonzero(~moving.any(axis=1))
        if len(still):
            hits[still] = np.where(self._n_contacts_loop(q0[still]) == 0, -1, 0)
        first, second = self._pairs[:, 0], self._pairs[:, 1]
        spheres, normal_columns = self._spheres, self._normal_columns
        first_ids, second_ids, pair_rates = self._first_ids, self._second_ids, pair_rate.tolist()
        margin = self.resolution + DISTANCE_TOLERANCE
        model, geom_distance = self.model, mujoco.mj_geomDistance
        data = self._data
        qpos = np.broadcast_to(model.qpos0, (len(q0), model.nq)).copy()
        index = np.zeros(len(q0), dtype=np.int64)
        active = np.flatnonzero(moving.any(axis=1))
        # A pair that does not move never limits a step: it sorts after every moving one,
        # past the first exact distance, which ends the search.
        denominator = np.where(moving, pair_rate, 1.0)
        excluded = np.where(moving, 0.0, np.inf)
        centre = np.empty((len(q0), model.ngeom, 3))
        frame = np.empty((len(q0), model.ngeom * 9))
        while len(active):
            for at, row in enumerate(active.tolist()):
                qpos[row, : self.dof] = q0[row] + (index[row] / n[row]) * delta[row]
                data.qpos[:] = qpos[row]
                mujoco.mj_kinematics(model, data)
                centre[at], frame[at] = data.geom_xpos, data.geom_xmat.ravel()
            # Lower bounds from bounding spheres (half-spaces for planes) ...
            size = len(active)
            apart = centre[:size, second] - centre[:size, first]
            normal = frame[:size, normal_columns].reshape(size, -1, 3)
            bound = np.concatenate(
                [np.sqrt(np.einsum("mij,mij->mi", apart[:, :spheres], apart[:, :spheres])),
                 np.einsum("mij,mij->mi", normal, apart[:, spheres:])], axis=1
            ) - self._radius_sum
            limits = (bound - margin) / denominator[active] + excluded[active]
            orders = np.argsort(limits, axis=1, kind="stable")
            going = []
            for row, order, limit in zip(active.tolist(), orders.tolist(), limits.tolist(),
                                         strict=True):
                rates = pair_rates[row]
                # ... then exact distances, nearest-in-time first, only while a pair's
                # bound could still be the one that limits the step (the path's sample
                # placed again where several share the model, which holds one at a time).
                if size > 1:
                    data.qpos[:] = qpos[row]
                    mujoco.mj_kinematics(model, data)
                best, hit = np.inf, False
                for k in order:
                    if limit[k] >= best:
                        break
                    cutoff = margin + best * rates[k] if best < np.inf else 1e3
                    distance = geom_distance(model, data, first_ids[k], second_ids[k], cutoff,
                                             None)
                    if distance < margin:
                        hit = True
                        break
                    best = min(best, (distance - margin) / rates[k])
                if hit:
                    mujoco.mj_collision(model, data)
                    if data.ncon:
                        hits[row] = index[row]
                        continue
                    index[row] += 1
                else:
                    index[row] += 1 + int(best * n[row])
                if index[row] <= n[row]:
                    going.append(row)
            active = np.array(going, dtype=np.int64)
        return hits
