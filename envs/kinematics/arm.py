"""The common contract of every arm: parameters as frozen data, FK, all-branch IK.

Subclasses supply the closed-form maths (``_fk``, ``_ik_candidates``); this base class owns
input validation, angle wrapping, joint-limit checks and the NaN convention, so every arm
answers bad input and unreachable poses the same way.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from functools import cached_property
from typing import ClassVar

import numpy as np

from .rotations import (
    ORTHONORMAL_TOL,
    as_float_array,
    validate_rotation,
    validate_rotation_scalar,
    wrap_angle,
)

#: A branch counts as inside its joint limits up to this slack (rad or m), so a solution
#: that lands on a limit within rounding is not thrown away. Values are never clamped.
LIMIT_TOL = 1e-9

REVOLUTE, PRISMATIC = "revolute", "prismatic"

#: Poses solved per pass inside ``ik`` (a batch is split so temporaries stay in cache).
IK_CHUNK = 2048


@dataclass(frozen=True, eq=False)
class Arm(ABC):
    """Base class: subclasses are frozen dataclasses whose fields are the arm's parameters.

    Every subclass has the fields ``joint_limits`` ((dof, 2) lower/upper, rad or m) and
    ``home`` ((dof,) configuration inside the limits), stored as read-only arrays.
    """

    name: ClassVar[str]
    joint_names: ClassVar[tuple[str, ...]]
    joint_types: ClassVar[tuple[str, ...]]
    branch_labels: ClassVar[tuple[str, ...]]
    #: "pose" arms read the whole (4, 4) target; "position" arms only its translation.
    target: ClassVar[str] = "pose"

    joint_limits: np.ndarray
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
            raise ValueError(f"{self.name}: every joint limit needs lower < upper")
        revolute = self.revolute_mask
        if np.any(np.abs(limits[revolute]) > np.pi + 1e-12):
            # Branches are reported wrapped to [−π, π); wider ranges would make K ambiguous.
            raise ValueError(f"{self.name}: revolute joint limits must lie within [-pi, pi]")
        home = as_float_array(self.home, f"{self.name} home").copy()
        if home.shape != (self.dof,):
            raise ValueError(f"{self.name}: home must have shape ({self.dof},), got {home.shape}")
        if np.any(home < limits[:, 0]) or np.any(home > limits[:, 1]):
            raise ValueError(f"{self.name}: home configuration lies outside the joint limits")
        limits.flags.writeable = False
        home.flags.writeable = False
        object.__setattr__(self, "joint_limits", limits)
        object.__setattr__(self, "home", home)
        self._check_parameters()

    def _check_parameters(self) -> None:  # noqa: B027 (optional hook)
        """Subclasses raise ``ValueError`` for impossible dimensions."""

    # ----------------------------------------------------------------------------- contract
    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def n_branches(self) -> int:
        return len(self.branch_labels)

    @property
    def revolute_mask(self) -> np.ndarray:
        return np.array([kind == REVOLUTE for kind in self.joint_types])

    def fk(self, q) -> np.ndarray:
        """Pose (…, 4, 4) of the output frame for joint values ``q`` (…, dof)."""
        q = as_float_array(q, "q")
        if q.ndim < 1 or q.shape[-1] != self.dof:
            raise ValueError(f"q must have shape (..., {self.dof}) for {self.name}, got {q.shape}")
        return self._fk(q)

    def ik(self, pose) -> tuple[np.ndarray, np.ndarray]:
        """Every closed-form solution for ``pose`` (…, 4, 4).

        Returns ``Q`` (…, K, dof) in the fixed order of ``branch_labels`` and ``ok`` (…, K):
        a branch is valid when it exists and lies inside ``joint_limits``; invalid rows are
        NaN. An unreachable pose is not an error: all its rows are invalid.
        """
        if (
            type(pose) is np.ndarray
            and pose.shape == (4, 4)
            and pose.dtype.kind in "fiu"
            and self._has_single_path
        ):
            return self._ik_one(pose)
        pose = as_float_array(pose, "pose")
        if pose.ndim < 2 or pose.shape[-2:] != (4, 4):
            raise ValueError(f"pose must have shape (..., 4, 4), got {pose.shape}")
        batch_shape = pose.shape[:-2]
        flat = pose.reshape(-1, 4, 4)
        if np.any(np.abs(flat[:, 3, :] - (0.0, 0.0, 0.0, 1.0)) > ORTHONORMAL_TOL):
            raise ValueError("pose bottom row must be (0, 0, 0, 1)")
        candidates = np.empty((flat.shape[0], self.n_branches, self.dof))
        ok = np.empty((flat.shape[0], self.n_branches), dtype=bool)
        # Chunks keep the temporaries in cache: on 100k poses this is ~3x faster than one pass.
        for start in range(0, flat.shape[0], IK_CHUNK):
            chunk = flat[start : start + IK_CHUNK]
            if self.target == "pose":
                validate_rotation(chunk[..., :3, :3], "pose")
            candidates[start : start + IK_CHUNK], ok[start : start + IK_CHUNK] = (
                self._checked_candidates(chunk)
            )
        shape = (*batch_shape, self.n_branches)
        return candidates.reshape((*shape, self.dof)), ok.reshape(shape)

    def _ik_one(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One (4, 4) array through ``_ik_single``: the same checks, in Python floats."""
        m = pose.tolist()
        if not all(map(math.isfinite, (*m[0], *m[1], *m[2], *m[3]))):
            raise ValueError("pose contains NaN or inf")
        bottom = m[3]
        if (abs(bottom[0]) > ORTHONORMAL_TOL or abs(bottom[1]) > ORTHONORMAL_TOL
                or abs(bottom[2]) > ORTHONORMAL_TOL or abs(bottom[3] - 1.0) > ORTHONORMAL_TOL):
            raise ValueError("pose bottom row must be (0, 0, 0, 1)")
        if self.target == "pose":
            validate_rotation_scalar(m, "pose")
        rows, ok = [], []
        limits, revolute = self._checked_limits, self._revolute_joints
        for row in self._ik_single(m):
            valid = row is not None
            if valid:
                for joint in revolute:
                    if row[joint] >= math.pi:  # the one value of [−π, π] outside [−π, π)
                        row[joint] -= 2.0 * math.pi
                for joint, lower, upper in limits:
                    if not lower - LIMIT_TOL <= row[joint] <= upper + LIMIT_TOL:
                        valid = False
                        break
            rows.append(row if valid else self._nan_row)
            ok.append(valid)
        return np.array(rows), np.array(ok)

    @cached_property
    def _has_single_path(self) -> bool:
        return type(self)._ik_single is not Arm._ik_single

    @cached_property
    def _revolute_joints(self) -> tuple[int, ...]:
        return tuple(int(joint) for joint in np.flatnonzero(self.revolute_mask))

    @cached_property
    def _checked_limits(self) -> tuple[tuple[int, float, float], ...]:
        """(joint, lower, upper) of every joint whose range a wrapped value can leave."""
        return tuple(
            (joint, float(lower), float(upper))
            for joint, (lower, upper) in enumerate(self.joint_limits)
            if not (self.joint_types[joint] == REVOLUTE and lower <= -np.pi and upper >= np.pi)
        )

    @cached_property
    def _nan_row(self) -> tuple[float, ...]:
        return (math.nan,) * self.dof

    def _ik_single(self, m: list[list[float]]) -> list[list[float] | None]:
        """Optional fast path for one pose (``m`` its nested list): the K raw rows as lists,
        revolute values in [−π, π], None where a branch does not exist. Arms that define it
        must agree with ``_ik_candidates`` (tests compare the two)."""
        raise NotImplementedError

    def _checked_candidates(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(invalid="ignore"):
            raw = self._ik_candidates(pose)
            if isinstance(raw, np.ndarray):
                raw = [raw[..., joint] for joint in range(self.dof)]
            # Joint by joint on (…, K) columns: wrapping and limit checks on the stacked
            # (…, K, dof) array would pass over a short strided axis, slowly.
            columns, ok = [], None
            for joint, (lower, upper) in enumerate(self.joint_limits):
                values = raw[joint]
                if self.joint_types[joint] == REVOLUTE:
                    values = wrap_angle(values)
                    if lower <= -np.pi and upper >= np.pi:
                        inside = values == values  # a wrapped angle fits; NaN does not
                    else:
                        inside = (values >= lower - LIMIT_TOL) & (values <= upper + LIMIT_TOL)
                else:
                    inside = (values >= lower - LIMIT_TOL) & (values <= upper + LIMIT_TOL)
                columns.append(values)
                ok = inside if ok is None else ok & inside
        candidates = np.stack(columns, axis=-1)
        candidates[~ok] = np.nan
        return candidates, ok

    def within_limits(self, q) -> np.ndarray:
        """(…,) bool: every joint of ``q`` (…, dof) inside its limits (with ``LIMIT_TOL``)."""
        q = np.asarray(q, dtype=np.float64)
        lower, upper = self.joint_limits[:, 0], self.joint_limits[:, 1]
        return np.all((q >= lower - LIMIT_TOL) & (q <= upper + LIMIT_TOL), axis=-1)

    # ------------------------------------------------------------------------ for subclasses
    @abstractmethod
    def _fk(self, q: np.ndarray) -> np.ndarray: ...

    @abstractmethod
    def _ik_candidates(self, pose: np.ndarray) -> np.ndarray | list[np.ndarray]:
        """Raw candidates in branch order, NaN where a branch does not exist: a (…, K, dof)
        array, or the dof joint columns, each (…, K) (faster for big batches)."""
