"""The single-pose path: every arm's scalar kernel, compiled with numba, behind one driver.

Why: on one pose the batched numpy solvers pay numpy's per-call overhead (~1 µs a ufunc,
85–240 µs a pose) for a few hundred flops. One mechanism serves every arm:

* each arm class names a **scalar kernel** (``Arm._kernel``): plain Python on floats and
  ``math``, the same formulas as its numpy ``_ik_candidates``, writing the closed-form rows
  of one pose into a NaN-filled (Kc, dof) array;
* one **driver** per kernel, compiled here, runs the shared input checks
  (``pose_status``), the kernel, and the shared reduction to joint limits and turn windows
  (``finish_rows``, the scalar statement of ``Arm._checked_candidates``);
* tests hold every arm's compiled path to its numpy path (``ik_batched``) on random,
  singular, boundary and unreachable poses.

The numpy solvers stay the reference: every batch goes through them, and so do single
poses when numba is missing (``single_pose_solver`` returns None). The kernels do the
numpy solvers' arithmetic in the same order, so with numpy's own SIMD transcendentals off
the two agree bit for bit on every arm whose numpy solver does not multiply rotations with
matmul/einsum (tested in a subprocess). In numpy's default build they agree to 1e-12:
its AVX-512 float64 ``arctan2`` and ``arccos`` loops differ from the C library's
``atan2``/``acos`` (used by numba and by ``math``) by one ulp on a few percent of inputs
(measured: 2.8 % of atan2, 9.4 % of acos calls over 10⁶ random inputs).

Why numba and not a pure-Python scalar path: numba is the project's compiled-kernel tool
and ships wheels for every platform numpy does. The pure-Python twin of the
anthropomorphic solver took 14–22 µs for 8 branches; with turn branches (UR5e: 256) the
reduction alone costs ~100 µs in Python. Compiling the numpy solvers themselves with numba
was measured too: bitwise equal and 6.8 µs, but 74 s of compilation for one arm, and five
arms use batched matmul/einsum numba does not support. The scalar kernels compile in about
a second each, on the first single-pose call of each arm class in a process (nothing is
written to disk).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .arm import LIMIT_TOL, LINEAR, TURNS, TWO_PI, WRAPPED_FULL, Arm, Kernel, SinglePoseSolver
from .rotations import ORTHONORMAL_TOL

#: ``pose_status`` codes -> the messages the numpy path raises for the same input.
STATUS_MESSAGES = {
    1: "pose contains NaN or inf",
    2: "pose bottom row must be (0, 0, 0, 1)",
    3: f"pose rotation block is not orthonormal (tolerance {ORTHONORMAL_TOL:g})",
    4: "pose rotation block is a reflection (det < 0), not a rotation",
}


def pose_status(m: np.ndarray, check_rotation: bool) -> int:
    """0 if the (4, 4) array ``m`` is a valid target, else a ``STATUS_MESSAGES`` code.

    The checks of ``as_float_array``, ``Arm.ik_batched`` and ``validate_rotation``, in that
    order and with the same arithmetic (dot products summed left to right)."""
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


def finish_rows(
    raw: np.ndarray,
    modes: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    slots: np.ndarray,
    q: np.ndarray,
    ok: np.ndarray,
) -> None:
    """``Arm._checked_candidates`` for one pose: raw closed-form rows (Kc, dof) -> every
    branch's row ``q`` (K, dof) and ``ok`` (K,), K = Kc × Π slots (last joint fastest).

    The same floating-point operations as the numpy path, so values agree bitwise given
    the same raw rows. The helpers called in the loops take and return scalars only: with
    the per-joint and per-branch steps as helpers taking the arrays (numba reference-counts
    an inlined helper's array arguments), UR5e's 256 branches measured ~20 % slower."""
    kc, dof = raw.shape
    turns = q.shape[0] // kc
    width = _slot_width(slots)
    values = np.empty((dof, width))
    inside = np.zeros((dof, width), dtype=np.bool_)
    for closed in range(kc):
        for joint in range(dof):
            mode, low, high, count = modes[joint], lower[joint], upper[joint], slots[joint]
            v = raw[closed, joint]
            if v != v:  # the branch does not exist
                for slot in range(count):
                    values[joint, slot] = math.nan
                    inside[joint, slot] = False
                continue
            v = _wrap_joint_value(v, mode, low)
            for slot in range(count):
                w = v + TWO_PI * slot if count > 1 else v
                values[joint, slot] = w
                inside[joint, slot] = _within_limits(w, mode, low, high)
        for turn in range(turns):
            row = closed * turns + turn
            rest, valid = turn, True
            for joint in range(dof - 1, -1, -1):
                count = slots[joint]
                slot = rest % count
                rest //= count
                q[row, joint] = values[joint, slot]
                if not inside[joint, slot]:
                    valid = False
            ok[row] = valid
            if not valid:
                for joint in range(dof):
                    q[row, joint] = math.nan


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


#: The helpers of ``finish_rows``, registered with numba to be inlined into it.
_FINISH_HELPERS = (_slot_width, _wrap_joint_value, _within_limits)


def kernel_helpers() -> tuple[Callable, ...]:
    """Module-level scalar functions the kernels call (compiled along with them)."""
    from .dual import zxz_scalar
    from .ur import singular_wrist_turn
    from .wrist import put_wrist_rows, wrist_branches_scalar

    return (wrist_branches_scalar, put_wrist_rows, zxz_scalar, singular_wrist_turn)


@functools.cache
def _numba() -> Any:
    # The numba module, or None without numba. Typed Any, not ``types.ModuleType | None``:
    # this package may import only numpy and the typing modules (test_purity.py).
    try:
        import numba
    except ImportError:  # the numpy path answers every pose, only slower
        return None
    from numba.extending import register_jitable

    for helper in kernel_helpers():
        register_jitable(helper)
    for helper in _FINISH_HELPERS:
        # A fresh decorator per helper: register_jitable pops ``inline`` from its options.
        register_jitable(inline="always")(helper)
    return numba


@functools.cache
def _shared() -> tuple[Callable, Callable]:
    numba = _numba()
    return numba.njit(pose_status), numba.njit(finish_rows)


@functools.cache
def _driver(kernel: Kernel) -> Callable | None:
    """The compiled single-pose solver around ``kernel`` (one per kernel function)."""
    numba = _numba()
    if numba is None:
        return None
    status_of, finish = _shared()
    solve_rows = numba.njit(kernel)

    @numba.njit
    def drive(
        m: np.ndarray,
        params: np.ndarray,
        kc: int,
        dof: int,
        k: int,
        check_rotation: bool,
        modes: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        slots: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, int]:
        q = np.empty((k, dof))
        ok = np.zeros(k, dtype=np.bool_)
        status = status_of(m, check_rotation)
        if status != 0:
            return q, ok, status
        raw = np.full((kc, dof), np.nan)
        solve_rows(m, params, raw)
        finish(raw, modes, lower, upper, slots, q, ok)
        return q, ok, 0

    return drive


def single_pose_solver(arm: Arm) -> SinglePoseSolver | None:
    """``pose (4, 4) -> (Q (K, dof), ok (K,))`` for ``arm``, or None without numba."""
    kernel = type(arm)._kernel
    if kernel is None:
        return None
    drive = _driver(kernel)
    if drive is None:
        return None
    params = np.ascontiguousarray(arm._kernel_parameters(), dtype=np.float64)
    modes = np.array([mode for mode, _, _, _ in arm._joint_modes], dtype=np.int64)
    lower = np.array([low for _, low, _, _ in arm._joint_modes], dtype=np.float64)
    upper = np.array([high for _, _, high, _ in arm._joint_modes], dtype=np.float64)
    slots = np.array([count for _, _, _, count in arm._joint_modes], dtype=np.int64)
    kc, dof, k = arm.n_closed_form, arm.dof, arm.n_branches
    check_rotation = arm.target == "pose"

    def solve(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if pose.dtype != np.float64 or not pose.flags.c_contiguous:
            pose = np.ascontiguousarray(pose, dtype=np.float64)
        q, ok, status = drive(pose, params, kc, dof, k, check_rotation, modes, lower, upper,
                              slots)
        if status:
            raise ValueError(STATUS_MESSAGES[status])
        return q, ok

    return solve
