"""Every arm's inverse kinematics, batched or one pose: one driver around per-arm scalar
kernels, compiled with numba.

Each arm's closed form is written **once**, as a scalar kernel (``Arm._kernel``): plain
Python on floats and ``math`` that writes the closed-form rows of one (4, 4) pose into a
NaN-filled (Kc, dof) array. One driver, ``solve_poses``, serves every arm and every batch
size: per pose the shared input checks (``pose_status``), the arm's kernel (picked from
``KERNELS`` by number) and the shared reduction to joint limits and turn windows
(``finish_rows``). ``Arm.ik`` calls it for one pose and for a million alike, so a pose's
branches never depend on the batch it came in.

numba compiles the driver with every kernel once per machine (about 7 s) into an on-disk
cache under a directory named by a hash of this package's sources (numba alone would not
notice an edited kernel: it stamps the cache with the driver's file only); a process then
loads it in ~0.4 s (numba's import included) on its first IK call. Without numba the very
same functions run interpreted: the same answers (tested bit for bit against the compiled
ones), ~1,000× slower. This package imports numba only here, lazily, so it stays
importable with numpy alone.

Why scalar kernels and not the batched numpy solvers of earlier versions: on one pose numpy
pays ~1 µs per ufunc call (80–320 µs a pose, against 3–9 µs compiled), the kernels are
as fast on batches (docs/kinematics_opw_ur.md), and two copies of every closed form —
numpy and scalar — only agreed to an ulp (numpy's AVX-512 arctan2/arccos differ from the C
library's on a few percent of inputs). Compiling the numpy solvers with numba was measured
too: 74 s of compilation for one arm, and matmul/einsum on batches numba does not support.
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .anthropomorphic import anthropomorphic_kernel
from .arm import LIMIT_TOL, LINEAR, TURNS, TWO_PI, WRAPPED_FULL, Arm, Kernel
from .cartesian import cartesian_kernel
from .cylindrical import cylindrical_kernel
from .cylindrical4 import cylindrical4_kernel
from .dual import ppr_prr_kernel, rrp_rpp_kernel, rrr_ppp_kernel, zxz_branches
from .opw import opw_kernel
from .rod import rod_kernel
from .rotations import ORTHONORMAL_TOL
from .spherical import spherical_kernel
from .ur import singular_wrist_turn, ur_kernel
from .wrist import put_wrist_rows, wrist_branches

#: Every arm's kernel; an arm's kernel number is its index here (``closed_form_rows``).
KERNELS: tuple[Kernel, ...] = (
    anthropomorphic_kernel,
    cartesian_kernel,
    cylindrical_kernel,
    cylindrical4_kernel,
    rrp_rpp_kernel,
    rrr_ppp_kernel,
    ppr_prr_kernel,
    opw_kernel,
    rod_kernel,
    spherical_kernel,
    ur_kernel,
)

#: Scalar functions the kernels call (compiled along with them).
KERNEL_HELPERS: tuple[Callable, ...] = (
    wrist_branches, put_wrist_rows, zxz_branches, singular_wrist_turn,
)

#: ``pose_status`` codes -> the messages ``Arm.ik`` raises.
STATUS_MESSAGES = {
    1: "pose contains NaN or inf",
    2: "pose bottom row must be (0, 0, 0, 1)",
    3: f"pose rotation block is not orthonormal (tolerance {ORTHONORMAL_TOL:g})",
    4: "pose rotation block is a reflection (det < 0), not a rotation",
}

#: ``poses (N, 4, 4) -> (Q (N, K, dof), ok (N, K), reach (N,))`` for one arm.
Solver = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


def pose_status(m: np.ndarray, check_rotation: bool) -> int:
    """0 if the (4, 4) array ``m`` is a valid target, else a ``STATUS_MESSAGES`` code: finite,
    bottom row (0, 0, 0, 1) and, for ``check_rotation``, a rotation block orthonormal to
    ``ORTHONORMAL_TOL`` and proper (det > 0)."""
    for i in range(4):
        for j in range(4):
            if not math.isfinite(m[i, j]):
                return 1
    tol = ORTHONORMAL_TOL
    if abs(m[3, 0]) > tol or abs(m[3, 1]) > tol or abs(m[3, 2]) > tol or abs(m[3, 3] - 1.0) > tol:
        return 2
    if not check_rotation:
        return 0
    x0, x1, x2 = m[0, 0], m[1, 0], m[2, 0]
    y0, y1, y2 = m[0, 1], m[1, 1], m[2, 1]
    z0, z1, z2 = m[0, 2], m[1, 2], m[2, 2]
    if (
        abs(x0 * x0 + x1 * x1 + x2 * x2 - 1.0) > tol
        or abs(y0 * y0 + y1 * y1 + y2 * y2 - 1.0) > tol
        or abs(z0 * z0 + z1 * z1 + z2 * z2 - 1.0) > tol
        or abs(x0 * y0 + x1 * y1 + x2 * y2) > tol
        or abs(y0 * z0 + y1 * z1 + y2 * z2) > tol
        or abs(z0 * x0 + z1 * x1 + z2 * x2) > tol
    ):
        return 3
    c0, c1, c2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0
    if c0 * z0 + c1 * z1 + c2 * z2 < 0.0:
        return 4
    return 0


def finish_rows(  # noqa: C901 (one loop nest on purpose: see the docstring)
    raw: np.ndarray,
    modes: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    slots: np.ndarray,
    q: np.ndarray,
    ok: np.ndarray,
    pose: int,
    values: np.ndarray,
    inside: np.ndarray,
) -> bool:
    """Raw closed-form rows (Kc, dof) of pose number ``pose`` -> every branch's row
    ``q[pose]`` (K, dof) and ``ok[pose]`` (K,), K = Kc × Π slots (last joint fastest):
    revolute values moved to their representatives (``arm.py``'s module docstring),
    checked against the limits, invalid rows NaN. Returns whether some closed-form row
    exists (the limits aside). ``values`` and ``inside`` are scratch tables
    (dof, ``_slot_width(slots)``).

    Written for speed inside the driver's loop over poses: no allocation and no array view
    per pose, a closed-form row that does not exist skipped whole, arms without turn
    windows spared the window arithmetic, and one loop nest whose helpers take and return
    scalars only: numba reference-counts a helper's array arguments, and splitting the
    per-row steps into array-taking helpers measured 10–25 % slower (inlined or not)."""
    kc, dof = raw.shape
    turns = q.shape[1] // kc
    reach = False
    for closed in range(kc):
        exists = True
        for joint in range(dof):
            if raw[closed, joint] != raw[closed, joint]:
                exists = False
        if not exists:  # every branch of this closed-form row is invalid
            for row in range(closed * turns, (closed + 1) * turns):
                ok[pose, row] = False
                for joint in range(dof):
                    q[pose, row, joint] = math.nan
            continue
        reach = True
        if turns == 1:  # no turn windows: branch ``closed`` is the row itself
            valid = True
            for joint in range(dof):
                mode, low = modes[joint], lower[joint]
                v = _wrap_joint_value(raw[closed, joint], mode, low)
                q[pose, closed, joint] = v
                if not _within_limits(v, mode, low, upper[joint]):
                    valid = False
            ok[pose, closed] = valid
            if not valid:
                for joint in range(dof):
                    q[pose, closed, joint] = math.nan
            continue
        # Each joint's window values and limit checks once, then one branch per
        # combination of windows (first turned joint slowest).
        for joint in range(dof):
            mode, low, high, count = modes[joint], lower[joint], upper[joint], slots[joint]
            v = _wrap_joint_value(raw[closed, joint], mode, low)
            for slot in range(count):
                w = v + TWO_PI * slot if count > 1 else v
                values[joint, slot] = w
                inside[joint, slot] = _within_limits(w, mode, low, high)
        for turn in range(turns):
            row = closed * turns + turn
            rest, valid = turn, True
            for joint in range(dof - 1, -1, -1):
                count = slots[joint]
                slot = 0
                if count > 1:
                    slot = rest % count
                    rest //= count
                q[pose, row, joint] = values[joint, slot]
                if not inside[joint, slot]:
                    valid = False
            ok[pose, row] = valid
            if not valid:
                for joint in range(dof):
                    q[pose, row, joint] = math.nan
    return reach


def _slot_width(slots: np.ndarray) -> int:
    """The most turn slots of any joint (at least 1): the width of the per-joint tables."""
    width = 1
    for joint in range(len(slots)):
        width = max(width, slots[joint])
    return width


def _wrap_joint_value(v: float, mode: int, low: float) -> float:
    """A closed-form joint value moved into its mode's base window: for ``TURNS`` the
    2π-window starting at the lower limit (less ``LIMIT_TOL``), for other revolute modes
    [−π, π); a ``LINEAR`` value is kept as it is."""
    if mode == TURNS:
        v = v - TWO_PI * np.floor((v - (low - LIMIT_TOL)) / TWO_PI)
    elif mode != LINEAR:
        v = v - TWO_PI * np.floor((v + np.pi) / TWO_PI)
    return v


def _within_limits(w: float, mode: int, low: float, high: float) -> bool:
    """Whether joint value ``w`` is inside [low, high] (within ``LIMIT_TOL``); always, for
    a full wrapped joint (every value is one of its turns)."""
    if mode == WRAPPED_FULL:
        return True
    return w >= low - LIMIT_TOL and w <= high + LIMIT_TOL


#: The scalar helpers of ``finish_rows``, registered with numba (LLVM inlines them; numba's
#: own ``inline="always"`` was no faster and raised pedantic IR warnings when compiling).
_FINISH_HELPERS = (_slot_width, _wrap_joint_value, _within_limits)


def closed_form_rows(kernel: int, m: np.ndarray, params: np.ndarray, out: np.ndarray) -> None:
    """Run ``KERNELS[kernel]`` (a chain of calls: numba cannot index a tuple of functions)."""
    if kernel == 0:
        anthropomorphic_kernel(m, params, out)
    elif kernel == 1:
        cartesian_kernel(m, params, out)
    elif kernel == 2:
        cylindrical_kernel(m, params, out)
    elif kernel == 3:
        cylindrical4_kernel(m, params, out)
    elif kernel == 4:
        rrp_rpp_kernel(m, params, out)
    elif kernel == 5:
        rrr_ppp_kernel(m, params, out)
    elif kernel == 6:
        ppr_prr_kernel(m, params, out)
    elif kernel == 7:
        opw_kernel(m, params, out)
    elif kernel == 8:
        rod_kernel(m, params, out)
    elif kernel == 9:
        spherical_kernel(m, params, out)
    else:
        ur_kernel(m, params, out)


def solve_poses(
    kernel: int,
    poses: np.ndarray,
    params: np.ndarray,
    kc: int,
    dof: int,
    k: int,
    check_rotation: bool,
    modes: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    slots: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """Every branch of every pose of ``poses`` (N, 4, 4) for kernel number ``kernel``.

    Returns ``(Q (N, K, dof), ok (N, K), reach (N,), bad, status)``: ``reach`` is whether
    some closed-form row exists before the joint limits; ``bad`` is the first invalid
    pose (−1 if none) and ``status`` its ``STATUS_MESSAGES`` code, checked for every pose
    before any is solved."""
    n = poses.shape[0]
    q = np.empty((n, k, dof))
    ok = np.zeros((n, k), dtype=np.bool_)
    reach = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        status = pose_status(poses[i], check_rotation)
        if status != 0:
            return q, ok, reach, i, status
    raw = np.empty((kc, dof))
    width = _slot_width(slots)
    values = np.empty((dof, width))
    inside = np.zeros((dof, width), dtype=np.bool_)
    for i in range(n):
        raw[:] = math.nan
        closed_form_rows(kernel, poses[i], params, raw)
        reach[i] = finish_rows(raw, modes, lower, upper, slots, q, ok, i, values, inside)
    return q, ok, reach, -1, 0


def kernel_number(cls: type[Arm]) -> int:
    """The index of ``cls._kernel`` in ``KERNELS``."""
    for number, kernel in enumerate(KERNELS):
        if cls._kernel is kernel:
            return number
    raise TypeError(
        f"{cls.__name__}._kernel is not one of envs.kinematics.compiled.KERNELS: a new "
        "closed form is added to KERNELS and to closed_form_rows"
    )


@functools.cache
def _numba() -> Any:
    # The numba module, or None without numba. Typed Any, not ``types.ModuleType | None``:
    # this package may import only numpy and the typing modules (test_purity.py).
    try:
        import numba
    except ImportError:  # the same functions run interpreted
        return None
    return numba


def source_digest(package: Path) -> str:
    """A hash of every ``.py`` file in ``package`` (names and contents), 16 hex digits."""
    digest = hashlib.sha256()
    for source in sorted(package.glob("*.py")):
        digest.update(source.name.encode())
        digest.update(source.read_bytes())
    return digest.hexdigest()[:16]


def cache_directory(package: Path | None = None) -> Path | None:
    """Where the kernels of ``package`` (default: this one, the compiled driver's) are
    cached: a directory named by the hash of its sources (:func:`writable_cache`)."""
    here = Path(__file__).resolve().parent if package is None else package
    return writable_cache(f"numba-{source_digest(here)}", here / "__pycache__")


def writable_cache(name: str, beside: Path) -> Path | None:
    """The directory ``name`` under ``NUMBA_CACHE_DIR`` if set, else under ``beside`` (the
    sources' ``__pycache__``), else under the user's cache directory: the first that can be
    made and written; None if none can (kernels are then compiled in every process)."""
    roots = [Path(os.environ["NUMBA_CACHE_DIR"])] if os.environ.get("NUMBA_CACHE_DIR") else []
    roots += [beside, Path.home() / ".cache" / "ikbranch"]
    for root in roots:
        directory = root / name
        try:
            directory.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(directory, os.W_OK):
            return directory
    return None


def cached_njit(function: Callable, directory: Path | None, root: Path,
                **options: Any) -> Any:
    """``numba.njit(**options)(function)`` cached on disk in ``directory``, under the path
    of the function's source file relative to ``root``, and stamped with a hash of that
    file's text; not cached where ``directory`` is None (none is writable).

    numba names a cache by the absolute path of the source, so a second checkout or virtual
    environment of the very same sources would compile everything again (minutes). Here
    only what the sources say counts: every install of one version that shares a
    ``NUMBA_CACHE_DIR`` (test workers, Ray workers, several venvs, a CI cache) compiles
    each kernel once. ``directory`` must be named by a hash of every source its kernels
    are compiled from (:func:`writable_cache`, :func:`source_digest`)."""
    numba = _numba()
    if directory is None:
        return numba.njit(**options)(function)
    cache = _portable_cache(str(directory), str(root.resolve()))
    if cache is None:
        # numba's own cache, in ``directory`` (NUMBA_CACHE_DIR's setting, read when a
        # function is decorated: restored at once so other packages keep their caches).
        saved = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = str(directory)
        try:
            return numba.njit(cache=True, **options)(function)
        finally:
            numba.config.CACHE_DIR = saved
    dispatcher = numba.njit(**options)(function)
    # What njit(cache=True) does, with this cache in place of numba's own (FunctionCache).
    dispatcher._cache = cache(function)
    return dispatcher


@functools.cache
def _text_hash(path: str) -> str:
    """sha256 of a source file's text, read once per process (a module holds many kernels)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@functools.cache
def _portable_cache(directory: str, root: str) -> type | None:
    """numba's ``FunctionCache`` with the locator of :func:`cached_njit`; None where this
    numba lacks the parts it is built from (a test then fails: every install compiles)."""
    from numba.core import caching

    if not all(hasattr(caching, name) for name in ("_CacheLocator", "CompileResultCacheImpl",
                                                   "FunctionCache")):
        return None

    class Locator(caching._CacheLocator):
        def __init__(self, py_func: Callable, py_file: str) -> None:
            self._lineno = py_func.__code__.co_firstlineno
            relative = Path(py_file).resolve().relative_to(root)
            self._path = str(Path(directory, *relative.parent.parts))
            self._stamp = _text_hash(py_file)

        def get_cache_path(self) -> str:
            return self._path

        def get_source_stamp(self) -> str:
            return self._stamp

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func: Callable, py_file: str) -> Any:
            locator = cls(py_func, py_file)
            try:
                locator.ensure_cache_path()
            except OSError:  # numba then says that no cache location is available
                return None
            return locator

    class Impl(caching.CompileResultCacheImpl):
        _locator_classes = [Locator]  # noqa: RUF012 (numba declares it a list)

    class Cache(caching.FunctionCache):
        _impl_class = Impl

    return Cache


@functools.cache
def compiled_solve_poses() -> Callable:
    """``solve_poses`` compiled (loaded from the on-disk cache after the first time), or the
    interpreted function itself without numba."""
    numba = _numba()
    if numba is None:
        return solve_poses
    import numba.extending

    for function in (*KERNELS, *KERNEL_HELPERS, pose_status, finish_rows, closed_form_rows):
        numba.extending.register_jitable(function)
    for helper in _FINISH_HELPERS:
        numba.extending.register_jitable(helper)
    # Without Python's lock, as the env's kernels (envs.jit): a vector env's groups
    # solve their resets' poses in threads of their own.
    return cached_njit(solve_poses, cache_directory(), Path(__file__).parent, nogil=True)


def driver_arguments(arm: Arm) -> tuple[Any, ...]:
    """``solve_poses``' arguments after the poses for ``arm``: (params, kc, dof, k,
    check_rotation, modes, lower, upper, slots)."""
    modes = np.array([mode for mode, _, _, _ in arm._joint_modes], dtype=np.int64)
    lower = np.array([low for _, low, _, _ in arm._joint_modes], dtype=np.float64)
    upper = np.array([high for _, _, high, _ in arm._joint_modes], dtype=np.float64)
    slots = np.array([count for _, _, _, count in arm._joint_modes], dtype=np.int64)
    params = np.ascontiguousarray(arm._kernel_parameters(), dtype=np.float64)
    return (params, arm.n_closed_form, arm.dof, arm.n_branches, arm.target == "pose", modes,
            lower, upper, slots)


def solver(arm: Arm) -> Solver:
    """``poses (N, 4, 4) float64 C-contiguous -> (Q, ok, reach)`` for ``arm``; raises
    ``ValueError`` (naming the pose for N > 1) for a non-finite or non-rigid pose."""
    kernel = kernel_number(type(arm))
    solve = compiled_solve_poses()
    arguments = driver_arguments(arm)

    def solve_for_arm(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        # A waypoint file's poses are frozen.
        q, ok, reach, bad, status = solve(kernel, writable(poses), *arguments)
        if status:
            where = f" (pose {bad} of the batch)" if len(poses) > 1 else ""
            raise ValueError(STATUS_MESSAGES[status] + where)
        return q, ok, reach

    return solve_for_arm


def writable(array: np.ndarray) -> np.ndarray:
    """``array`` as a kernel takes it: numba types a read-only array (a frozen parameter
    such as an arm's home, a view ``np.broadcast_to`` made) apart, and would compile the
    kernel again, beside the warm-up's, for it."""
    return array if array.flags.writeable else array.copy()


def warm_up() -> None:
    """Compile the driver into its on-disk cache (or load it), before parallel processes
    would each compile it (``make test``, ``make demo``)."""
    from . import make_arm

    arm = make_arm("cartesian")
    arm.ik(arm.fk(arm.home))
