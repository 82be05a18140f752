"""The compiled collision filter: bounds prove samples free, inner shapes prove them in
contact, MuJoCo decides the rest.

:class:`~envs.models.collision.CollisionChecker`'s ``"compiled"`` backend. It answers the
same questions as the exact backends (does configuration q touch anything closer than δ;
which grid sample of a linear path is the first to), with the same answers, but decides
most samples without MuJoCo. Its rooms:

- :mod:`.layout` — **the model as flat arrays** (:class:`CompiledScene`): the kinematic
  tree, every collision geom that ``mj_collision`` may test as a *container* that holds it
  and an *inner* shape that it holds, each inside a bounding sphere, and per pair the
  lever arms that bound how fast its distance can change (``docs/models.md``). No per-arm
  code: every model ``envs.models`` builds gets it.
- :mod:`.shapes` — **one small function per shape pair**: the distance of two containers
  as a lower bound (sphere/capsule/box/half-space pairs in closed form, box–box by
  separating axes, which never overestimates), of two inner shapes exactly.
- :mod:`.tree` — **forward kinematics of the tree** in the kernel, slot frames, path
  samples and how fast they move.
- :mod:`.lanes` — **16 samples at once**: a small C kernel (``lanes.c``) that proves
  samples free from cover spheres of the moving geoms, and in contact from points inside
  them as the witnesses below do, for the checks of several paths or configurations
  (the samples it proves neither way go on to the checks below).
- :mod:`.kernels` — **the checks**. At a sample, first every pair's bounding spheres, then
  the containers of the pairs that could matter: a sample at which every pair is provably
  farther than its contact margin (δ, plus ``DISTANCE_TOLERANCE``) is free, exactly as
  ``mj_collision`` would find it; a pair whose inner shapes are closer than its margin
  (less ``WITNESS_TOLERANCE``), or one's inner sphere or capsule as close to the other's
  cylinder itself, proves a contact MuJoCo's colliders report; any other
  sample goes to ``mj_kinematics`` + ``mj_collision`` on the checker's ``MjData``, called
  from the kernel (:mod:`envs.models.native`). So every verdict and every first colliding
  sample is MuJoCo's. A path's grid samples (t_i = i/n, as in the module docstring of
  :mod:`~envs.models.collision`) are visited in raked order (the middle of every
  unresolved interval, breadth first), and a free sample's bounds prove its neighbours on
  both sides free (conservative advancement: a pair at distance d approaching at rate
  ≤ L stays farther than the margin for |t − t_i| < (d − margin)/L). A verdict-only call
  stops at the first contact found; a first-sample call keeps resolving the samples
  before it.
- this module — :class:`CompiledFilter`, the kernels bound to one checker, and
  :class:`FilterStack`, the filters of several scenes of one model checked in one call
  (a vector env's sub-envs).

The kernels are compiled once per machine into numba's on-disk cache (``envs.jit``;
``warm_up`` does it ahead), loaded in well under a second afterwards.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import mujoco
import numpy as np

from ikbranch_gym.envs.kinematics.compiled import writable

from .. import native
from .kernels import (
    COUNTERS,
    LANE_FUNCTION,
    LANE_PATHS,
    LANE_SCENE,
    LANE_WORK,
    bound_configurations,
    bound_paths,
    make_bound,
    path_steps,
)
from .lanes import LaneScene, primitive_box_pairs
from .layout import (
    DISTANCE_TOLERANCE,
    PER_SCENE,
    WITNESS_TOLERANCE,
    CompiledScene,
    compile_scene,
    container,
    inner,
    refresh_static,
)


# --------------------------------------------------------------------------- the filter
class CompiledFilter:
    """The kernels bound to one checker's model and ``MjData`` (which must outlive it).

    ``model`` carries the checker's margins; ``pairs`` are its candidate pairs.
    Configurations are the leading ``dof`` qpos entries (the rest stay at ``qpos0``).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, dof: int,
                 pairs: np.ndarray) -> None:
        self._model, self._data = model, data
        #: Totals since construction, named by ``COUNTERS`` (benchmarks and tests read them).
        self.counters = np.zeros(len(COUNTERS), dtype=np.int64)
        exact = np.zeros((1, LANE_PATHS + 1), dtype=np.uint64)
        exact[0, :LANE_FUNCTION] = native.exact_addresses(model, data)
        self._bind(compile_scene(model, dof, pairs), exact)

    def _bind(self, scene: CompiledScene, exact: np.ndarray) -> None:
        """Read ``scene`` (one scene) and ``exact`` (its (1, 10) row: MuJoCo's addresses,
        then the lanes', ``kernels.LANE_FUNCTION``) from now on."""
        self.scene, self._exact = scene, exact
        self.lanes = LaneScene(scene, primitive_box_pairs(self._model, scene))
        exact[0, LANE_FUNCTION] = self.lanes.function if self.lanes.address else 0
        exact[0, LANE_SCENE] = self.lanes.address
        exact[0, LANE_WORK] = self.lanes.work_doubles
        exact[0, LANE_PATHS] = self.lanes.paths_function if self.lanes.address else 0
        # The kernels' leading arguments, built once (the arrays are refreshed in place).
        self._bound = make_bound(scene.tree, scene.geometry, scene.motion, exact, self.counters)

    def refresh_static(self, geoms: np.ndarray | None = None) -> None:
        """Follow changed static geoms of the model (see :func:`refresh_static`)."""
        refresh_static(self.scene, self._model, geoms)

    def contacts(self, rows: np.ndarray, need: int = 0) -> np.ndarray:
        """(M,) contact counts at configurations ``rows`` (M, dof): 0 where proven free,
        else MuJoCo's count. ``need`` > 0: only until ``need`` free rows are found (the
        rest −1, unchecked)."""
        out, how = np.empty(len(rows), dtype=np.int64), np.empty(len(rows), dtype=np.int8)
        bound_configurations(self._bound, _ONE_SCENE, writable(rows), need, False, out, how)
        return out

    def collide(self, rows: np.ndarray, need: int = 0) -> np.ndarray:
        """(M,) 0 where configuration ``rows[i]`` is free, > 0 where it is in contact (a
        count where MuJoCo decided, 1 where inner shapes proved it); ``need`` as in
        :meth:`contacts`."""
        return self.collide_how(rows, need)[0]

    def collide_how(self, rows: np.ndarray, need: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`collide`, and per row who decided it: ``kernels.BY_BOUNDS``,
        ``BY_WITNESS`` (a proof, with its tolerance) or ``BY_MUJOCO``."""
        out, how = np.empty(len(rows), dtype=np.int64), np.empty(len(rows), dtype=np.int8)
        bound_configurations(self._bound, _ONE_SCENE, writable(rows), need, True, out, how)
        return out, how

    def paths(self, start_rows: np.ndarray, end_rows: np.ndarray, steps: np.ndarray,
              first: bool) -> np.ndarray:
        """(M,) grid index of a colliding sample per path (−1: free), the lowest with
        ``first``; ``start_rows`` (M or 1, dof), ``end_rows`` (M, dof), ``steps`` (M,)."""
        out = np.empty(len(end_rows), dtype=np.int64)
        bound_paths(self._bound, _ONE_SCENE, writable(start_rows), writable(end_rows), steps,
                    first, out)
        return out


#: The scene index of every row of a filter of its own.
_ONE_SCENE = np.zeros(1, dtype=np.int64)


class FilterStack:
    """The filters of several scenes of one model as one (a vector env's sub-envs, each
    with its own clutter): their per-scene arrays (``layout.PER_SCENE``) stacked, so that
    one kernel call checks rows and paths of every scene, each row naming its scene.

    Each filter joins the stack: from then on it reads and refreshes its row of the
    stack's arrays, so a new clutter laid in one sub-env is what the stack checks too.
    """

    def __init__(self, filters: Sequence[CompiledFilter]) -> None:
        if not filters:
            raise ValueError("a filter stack needs at least one filter")
        first = filters[0].scene
        for other in filters[1:]:
            if not _same_model(first, other.scene):
                raise ValueError("a filter stack needs filters of one model")
        stacked = {name: np.ascontiguousarray(np.concatenate(
            [getattr(f.scene, name) for f in filters])) for name in PER_SCENE}
        self.scene = dataclasses.replace(first, **stacked)
        self._exact = np.ascontiguousarray(np.concatenate([f._exact for f in filters]))
        self.size = len(filters)
        for index, member in enumerate(filters):
            member._bind(dataclasses.replace(member.scene, **{
                name: array[index : index + 1] for name, array in stacked.items()}),
                self._exact[index : index + 1])
        self.counters = np.zeros(len(COUNTERS), dtype=np.int64)
        self._bound = make_bound(self.scene.tree, self.scene.geometry, self.scene.motion,
                                 self._exact, self.counters)

    def collide(self, scenes: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """(M,) 0 where configuration ``rows[i]`` is free in scene ``scenes[i]``, > 0 where
        it is in contact (:meth:`CompiledFilter.collide`)."""
        out, how = np.empty(len(rows), dtype=np.int64), np.empty(len(rows), dtype=np.int8)
        bound_configurations(self._bound, scenes, writable(rows), 0, True, out, how)
        return out

    def collide_how(self, scenes: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`collide`, and per row who decided it (``CompiledFilter.collide_how``)."""
        out, how = np.empty(len(rows), dtype=np.int64), np.empty(len(rows), dtype=np.int8)
        bound_configurations(self._bound, scenes, writable(rows), 0, True, out, how)
        return out, how

    def paths(self, scenes: np.ndarray, start_rows: np.ndarray, end_rows: np.ndarray,
              steps: np.ndarray, first: bool) -> np.ndarray:
        """:meth:`CompiledFilter.paths` of paths each in its scene ``scenes[m]``."""
        out = np.empty(len(end_rows), dtype=np.int64)
        bound_paths(self._bound, scenes, writable(start_rows), writable(end_rows), steps,
                    first, out)
        return out


def _same_model(one: CompiledScene, other: CompiledScene) -> bool:
    """Two scenes of one model: equal in every field but the per-scene ones."""
    for item in dataclasses.fields(one):
        if item.name in PER_SCENE:
            continue
        # (NaN rows: joints without a world-fixed line, ``layout.CompiledScene``.)
        if not np.array_equal(getattr(one, item.name), getattr(other, item.name),
                              equal_nan=True):
            return False
    return True


def warm_up(configurations: bool = True, paths: bool = True) -> None:
    """Compile (or load from numba's on-disk cache) every kernel with the argument types
    the checker passes, on a small model: ``make`` runs it once before the tests, so
    parallel test processes load the cache instead of compiling each. Neither the
    configuration nor the path kernels call the other: two processes may compile one each."""
    from ..collision import CollisionChecker
    from ..model import build_model

    model = build_model("anthropomorphic", "random_clutter")
    for pad in (True, False):
        checker = CollisionChecker(model, dof=6, pad=pad, backend="compiled")
        checker.refresh_static()
        q = np.zeros((2, 6))
        q[1, 1] = 0.5
        if configurations:
            checker.collides(q)
        if paths:
            checker.check_paths(q[0], q[1])
            checker.paths_collide(q[0], q)
            checker.paths_collide(q, q[::-1])


if __name__ == "__main__":
    warm_up()


__all__ = ["COUNTERS", "DISTANCE_TOLERANCE", "WITNESS_TOLERANCE", "CompiledFilter",
           "CompiledScene", "FilterStack", "compile_scene", "container", "inner", "path_steps",
           "refresh_static", "warm_up"]
