"""The common contract of every arm: parameters as frozen data, FK, all-branch IK.

Subclasses supply the closed-form maths (``_fk`` on batches of configurations, and ``_kernel``,
the closed-form IK of one pose, written once); this base class and the one IK driver
(``compiled.py``) own input validation, the reduction of revolute values to their
representatives inside the joint limits (turn branches included), joint-limit checks and
the NaN convention, so every arm answers bad input and unreachable poses the same way.

Revolute joints, by their limits (``docs/kinematics_opw_ur.md``, "Turn branches"):

* limits within [−π, π] (every seed arm): the closed-form value is wrapped to [−π, π)
  and checked against the limits, exactly as before turn branches existed;
* limits outside [−π, π]: the joint reports every 2π shift of the closed-form value that
  lies inside its limits, one per *turn window*. Window t of a joint with limits [lo, hi]
  holds the representative in [lo + 2πt, lo + 2π(t + 1)) (shifted down by ``LIMIT_TOL``
  so a value on the lower limit stays in window 0); there are
  N = ⌈(hi − lo)/2π⌉ windows, the most a generic value can occupy. The branches are every
  closed-form branch × every combination of windows (first turned joint slowest), so
  ``n_branches`` is fixed per arm and a pose masks the windows it cannot use. Values are
  never wrapped into a window they do not belong to, never clamped: travel between two
  branches is the real rotation.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from functools import cached_property
from itertools import product
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from .rotations import as_float_array

#: A branch counts as inside its joint limits up to this slack (rad or m), so a solution
#: that lands on a limit within rounding is not thrown away. Values are never clamped.
LIMIT_TOL = 1e-9

REVOLUTE, PRISMATIC = "revolute", "prismatic"

#: The most branches (closed-form × turn windows) an arm may enumerate: limits so wide
#: that they exceed it are a data-entry error, not a robot (UR5e: 256, IRB 2600: 72).
MAX_BRANCHES = 4096

TWO_PI = 2.0 * np.pi
#: Revolute limits within ±(π + this) count as "within [−π, π]" (wrapped joints).
_WITHIN_PI_TOL = 1e-12
#: Slack on the number of turn windows: a span of 4π (UR's ±360°) needs 2 windows, not 3.
_WINDOW_COUNT_TOL = 1e-9

# How the IK driver (``compiled.finish_rows``) treats each joint.
LINEAR, WRAPPED_FULL, WRAPPED, TURNS = 0, 1, 2, 3

#: A scalar kernel ``kernel(m, params, out)`` (``Arm._kernel``): writes the closed-form rows
#: of the (4, 4) pose ``m`` into ``out`` (Kc, dof).
Kernel = Callable[[np.ndarray, np.ndarray, np.ndarray], None]


def array_default(values: ArrayLike) -> Callable[[], np.ndarray]:
    """The ``default_factory`` of an arm's ``joint_limits`` or ``home`` field: ``values``
    (the module's frozen tuple of floats) as a new float64 array.

    A dataclass refuses an array as a plain default (arrays are unhashable); the field holds
    an array either way once ``Arm.__post_init__`` has validated it and made it read-only."""
    return lambda: np.array(values, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class Arm(ABC):
    """Base class: subclasses are frozen dataclasses whose fields are the arm's parameters.

    Every subclass has the fields ``joint_limits`` ((dof, 2) lower/upper, rad or m) and
    ``home`` ((dof,) configuration inside the limits), stored as read-only arrays, and the
    class attribute ``closed_form_labels`` (its closed-form branches, in solver order).
    ``branch_labels`` adds the turn windows of joints whose limits exceed [−π, π].
    """

    name: ClassVar[str]
    joint_names: ClassVar[tuple[str, ...]]
    joint_types: ClassVar[tuple[str, ...]]
    closed_form_labels: ClassVar[tuple[str, ...]]
    #: "pose" arms read the whole (4, 4) target; "position" arms only its translation.
    target: ClassVar[str] = "pose"
    #: True for two-arm systems: ``fk`` is one arm's output link relative to the other's,
    #: not a tool in the world, so world-frame tasks and cells are not for them.
    relative: ClassVar[bool] = False
    #: The arm's closed-form IK, its one statement (``envs/kinematics/compiled.py``):
    #: ``kernel(m, params, out)`` writes the closed-form rows of the (4, 4) float array ``m``
    #: into ``out`` (Kc, dof), which arrives NaN, in branch order and NaN where a branch does
    #: not exist; revolute values may be any 2π shift (the driver picks the
    #: representatives). ``params`` is ``_kernel_parameters()``. Plain Python on floats and
    #: ``math``, so numba compiles it and CPython runs it alike; listed in
    #: ``compiled.KERNELS``.
    _kernel: ClassVar[Kernel]

    #: Given as any (dof, 2) array-like; stored as a read-only float64 array.
    joint_limits: np.ndarray
    #: Given as any (dof,) array-like; stored as a read-only float64 array.
    home: np.ndarray

    def __post_init__(self) -> None:
        for field in fields(self):
            if field.name in ("joint_limits", "home"):
                continue
            value = getattr(self, field.name)
            if isinstance(value, (int, float)) and not np.isfinite(value):
                raise ValueError(f"{self.name}: parameter {field.name} must be finite")
        limits = as_float_array(self.joint_limits, f"{self.name} joint_limits").copy()
        if limits.shape != (self.dof, 2):
            raise ValueError(
                f"{self.name}: joint_limits must have shape ({self.dof}, 2), got {limits.shape}"
            )
        if np.any(limits[:, 0] >= limits[:, 1]):
            bad = int(np.flatnonzero(limits[:, 0] >= limits[:, 1])[0])
            raise ValueError(
                f"{self.name}: every joint limit needs lower < upper "
                f"(joint_limits of {self.joint_names[bad]}: {limits[bad].tolist()})"
            )
        home = as_float_array(self.home, f"{self.name} home").copy()
        if home.shape != (self.dof,):
            raise ValueError(f"{self.name}: home must have shape ({self.dof},), got {home.shape}")
        if np.any(home < limits[:, 0]) or np.any(home > limits[:, 1]):
            raise ValueError(f"{self.name}: home configuration lies outside the joint limits")
        limits.flags.writeable = False
        home.flags.writeable = False
        object.__setattr__(self, "joint_limits", limits)
        object.__setattr__(self, "home", home)
        if self.n_branches > MAX_BRANCHES:
            raise ValueError(
                f"{self.name}: joint_limits allow {self.n_branches} branches "
                f"({self.n_closed_form} closed-form × turn windows); at most {MAX_BRANCHES}"
            )
        self._check_parameters()

    def _check_parameters(self) -> None:  # noqa: B027 (optional hook)
        """Subclasses raise ``ValueError`` for impossible dimensions."""

    # ----------------------------------------------------------------------------- contract
    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def n_closed_form(self) -> int:
        """Closed-form branches per pose, before turn windows."""
        return len(self.closed_form_labels)

    @property
    def n_branches(self) -> int:
        return self.n_closed_form * self._n_turn_combinations

    @property
    def revolute_mask(self) -> np.ndarray:
        return np.array([kind == REVOLUTE for kind in self.joint_types])

    @cached_property
    def turn_windows(self) -> tuple[tuple[int, tuple[tuple[float, float], ...]], ...]:
        """(joint, windows) of every joint with more than one turn window; each window is
        the (lower, upper) range in rad of the joint values it reports (module docstring)."""
        windows = []
        for joint, (mode, lower, upper, slots) in enumerate(self._joint_modes):
            if mode == TURNS and slots > 1:
                windows.append((joint, tuple(
                    (lower + TWO_PI * t, min(lower + TWO_PI * (t + 1), upper))
                    for t in range(slots)
                )))
        return tuple(windows)

    @cached_property
    def branch_labels(self) -> tuple[str, ...]:
        """K labels: the closed-form label, then ``/name@lo..hi`` (degrees) for the turn
        window of every joint that has several, e.g. ``front/elbow-up/wrist+/j6@10..350``."""
        if not self.turn_windows:
            return tuple(self.closed_form_labels)
        parts = [
            [f"{self.joint_names[joint]}@{_degrees(lo)}..{_degrees(hi)}" for lo, hi in windows]
            for joint, windows in self.turn_windows
        ]
        return tuple(
            "/".join((closed, *turns))
            for closed in self.closed_form_labels
            for turns in product(*parts)
        )

    @cached_property
    def branch_closed_form(self) -> np.ndarray:
        """(K,) index into ``closed_form_labels`` of every branch."""
        index = np.repeat(np.arange(self.n_closed_form), self._n_turn_combinations)
        index.flags.writeable = False
        return index

    @cached_property
    def branch_turns(self) -> np.ndarray:
        """(K, J) turn window of every branch for the J joints of ``turn_windows``."""
        counts = [len(windows) for _, windows in self.turn_windows]
        combos = np.array(list(product(*(range(n) for n in counts))), dtype=int)
        combos = combos.reshape(self._n_turn_combinations, len(counts))
        turns = np.tile(combos, (self.n_closed_form, 1))
        turns.flags.writeable = False
        return turns

    def fk(self, q: ArrayLike) -> np.ndarray:
        """Pose (…, 4, 4) of the output frame for joint values ``q`` (…, dof)."""
        q = as_float_array(q, "q")
        if q.ndim < 1 or q.shape[-1] != self.dof:
            raise ValueError(f"q must have shape (..., {self.dof}) for {self.name}, got {q.shape}")
        return self._fk(q)

    def positions(self, q: ArrayLike) -> np.ndarray:
        """Position (…, 3) of the output frame for joint values ``q`` (…, dof): the
        translation of :meth:`fk`, the same bits, without the rotation where the arm's
        position has a formula of its own."""
        q = as_float_array(q, "q")
        if q.ndim < 1 or q.shape[-1] != self.dof:
            raise ValueError(f"q must have shape (..., {self.dof}) for {self.name}, got {q.shape}")
        return self._position(q)

    def ik(self, pose: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Every closed-form solution for ``pose`` (…, 4, 4), with every turn it allows.

        Returns ``Q`` (…, K, dof) in the fixed order of ``branch_labels`` and ``ok`` (…, K):
        a branch is valid when it exists and lies inside ``joint_limits``; invalid rows are
        NaN. An unreachable pose is not an error: all its rows are invalid.

        One pose or a million go through the same compiled driver and the arm's one
        closed form (``envs/kinematics/compiled.py``), pose by pose: a pose's branches do not
        depend on the batch it came in.
        """
        q, ok, _ = self._solve(pose)
        return q, ok

    def _solve(self, pose: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Q (…, K, dof), ok (…, K), reach (…,)) for ``pose`` (…, 4, 4)."""
        if (type(pose) is np.ndarray and pose.shape == (4, 4) and pose.dtype == np.float64
                and pose.flags.c_contiguous):
            # One pose, the common case of a controller loop: no copy, no conversion.
            q, ok, reach = self._solver(pose.reshape(1, 4, 4))
            return q[0], ok[0], reach.reshape(())
        # The driver checks every pose (finite, rigid) and names the first bad one.
        pose = as_float_array(pose, "pose", check_finite=False)
        if pose.ndim < 2 or pose.shape[-2:] != (4, 4):
            raise ValueError(f"pose must have shape (..., 4, 4), got {pose.shape}")
        batch_shape = pose.shape[:-2]
        q, ok, reach = self._solver(np.ascontiguousarray(pose.reshape(-1, 4, 4)))
        shape = (*batch_shape, self.n_branches)
        return q.reshape((*shape, self.dof)), ok.reshape(shape), reach.reshape(batch_shape)

    def reaches(self, pose: ArrayLike) -> np.ndarray:
        """(…,) bool: some closed-form branch exists for ``pose`` (…, 4, 4), the joint
        limits aside: where ``ik`` finds no valid branch, this tells "out of reach" (False)
        from "outside the joint limits" (True)."""
        return self._solve(pose)[2]

    def limit_overshoot(self, pose: ArrayLike) -> tuple[int, int, float, float] | None:
        """Why no branch reaches ``pose`` (4, 4) inside the limits when some would outside
        them: (closed-form branch, joint, its value, the limit it passes) of the
        closed-form solution nearest to the limits (the least, over branches, of the
        largest overshoot over joints; every turn of a revolute joint considered). None
        when the pose is out of reach or some branch lies inside the limits."""
        if self.ik(pose)[1].any() or not self.reaches(pose):
            return None
        q, ok = self._without_limits.ik(pose)
        lower, upper = self.joint_limits[:, 0], self.joint_limits[:, 1]
        nearest: tuple[float, int, int, float, float] | None = None
        for branch in np.flatnonzero(ok):
            worst: tuple[float, int, int, float, float] | None = None
            for joint in range(self.dof):
                value = float(q[branch, joint])
                if self.joint_types[joint] == REVOLUTE:  # the turn nearest the limits
                    turns = value + TWO_PI * np.arange(-3, 4)
                    excess = np.maximum(lower[joint] - turns, turns - upper[joint])
                    value = float(turns[int(np.argmin(excess))])
                over = max(float(lower[joint]) - value, value - float(upper[joint]))
                bound = float(lower[joint] if value < lower[joint] else upper[joint])
                if worst is None or over > worst[0]:
                    worst = (over, int(branch), joint, value, bound)
            if worst is not None and (nearest is None or worst[0] < nearest[0]):
                nearest = worst
        return None if nearest is None else nearest[1:]

    @cached_property
    def _without_limits(self) -> Arm:
        """This arm with every revolute joint free over a full turn and every prismatic one
        over ±1 km: its branches are the closed-form ones, whatever the limits."""
        wide = np.where(self.revolute_mask[:, None], [[-np.pi, np.pi]], [[-1e3, 1e3]])
        home = np.clip(self.home, wide[:, 0], wide[:, 1])
        return replace(self, joint_limits=wide, home=home)

    def within_limits(self, q: ArrayLike) -> np.ndarray:
        """(…,) bool: every joint of ``q`` (…, dof) inside its limits (with ``LIMIT_TOL``)."""
        q = np.asarray(q, dtype=np.float64)
        lower, upper = self.joint_limits[:, 0], self.joint_limits[:, 1]
        return np.all((q >= lower - LIMIT_TOL) & (q <= upper + LIMIT_TOL), axis=-1)

    # ------------------------------------------------------------------ limits and turns
    @cached_property
    def _joint_modes(self) -> tuple[tuple[int, float, float, int], ...]:
        """(mode, lower, upper, windows) per joint; see the module docstring."""
        modes = []
        for kind, (lower, upper) in zip(self.joint_types, self.joint_limits, strict=True):
            lower, upper = float(lower), float(upper)
            if kind != REVOLUTE:
                modes.append((LINEAR, lower, upper, 1))
            elif abs(lower) <= np.pi + _WITHIN_PI_TOL and abs(upper) <= np.pi + _WITHIN_PI_TOL:
                full = lower <= -np.pi and upper >= np.pi
                modes.append((WRAPPED_FULL if full else WRAPPED, lower, upper, 1))
            else:
                windows = max(1, math.ceil((upper - lower) / TWO_PI - _WINDOW_COUNT_TOL))
                modes.append((TURNS, lower, upper, windows))
        return tuple(modes)

    @cached_property
    def _n_turn_combinations(self) -> int:
        return math.prod(slots for _, _, _, slots in self._joint_modes)

    # ------------------------------------------------------------------------ compiled IK
    @cached_property
    def _solver(self) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]:
        from .compiled import solver  # lazily: it brings numba in (module docstring)

        return solver(self)

    def __getstate__(self) -> dict[str, Any]:
        # The solver is a closure (not picklable) and cheap to rebuild.
        state = self.__dict__.copy()
        state.pop("_solver", None)
        return state

    def _kernel_parameters(self) -> np.ndarray:
        """The float parameters ``_kernel`` reads, in its order (subclasses override)."""
        return np.zeros(0)

    # ------------------------------------------------------------------------ for subclasses
    @abstractmethod
    def _fk(self, q: np.ndarray) -> np.ndarray: ...

    def _position(self, q: np.ndarray) -> np.ndarray:
        """:meth:`positions` of checked ``q``: the translation of ``_fk`` (arms whose
        position has its own formula return that, and build ``_fk`` from it)."""
        return self._fk(q)[..., :3, 3]



def _degrees(angle: float) -> str:
    """A window edge for a label: degrees, 6 significant digits, no '-0'."""
    return f"{round(float(np.rad2deg(angle)), 6) + 0.0:g}"
