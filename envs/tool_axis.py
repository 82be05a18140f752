"""A free tool axis: a round tool (a spindle, a deburring burr, a welding torch) does its
job whatever its rotation about its own axis, so every pose may be reached turned about
the TCP's z axis by any of a set of sampled angles.

:class:`ToolAxisArm` wraps an arm: its branches are the arm's branches × the angles
(branch b, angle s is branch ``b·S + s``), the configuration of a branch is the arm's
closed-form branch (the tool's rotation is no reconfiguration), and its IK solves each
pose turned by each angle. Everything else (forward kinematics, limits, joint names) is
the arm's own, so the env, the planners and the DP price and plan over the larger ladder
unchanged: the DP stays exact over branch × angle. Pure numpy; no state.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.rotations import invert_pose, rot_z

#: The most angles a tool axis may be sampled at.
MAX_ANGLES = 73


def axis_angles(half_range: float, step: float) -> np.ndarray:
    """The sampled angles (rad): the multiples of ``step`` in [−half_range, half_range],
    0 among them; a full turn (half_range ≥ π) keeps +π's twin −π only once.
    ``ValueError`` for a bad range or step, or more than ``MAX_ANGLES`` angles."""
    half_range, step = float(half_range), float(step)
    if not (math.isfinite(half_range) and 0.0 <= half_range <= math.pi):
        raise ValueError(f"tool_axis range must lie in [0, π] rad, got {half_range!r}")
    if not (math.isfinite(step) and step > 0.0):
        raise ValueError(f"tool_axis step must be a positive angle, got {step!r}")
    count = math.floor(half_range / step + 1e-9)
    angles = step * np.arange(-count, count + 1)
    if len(angles) > 1 and angles[-1] - angles[0] >= 2 * math.pi - 1e-9:
        angles = angles[:-1]  # +π is −π
    if len(angles) > MAX_ANGLES:
        raise ValueError(f"tool_axis samples {len(angles)} angles; at most {MAX_ANGLES} "
                         "(a larger step, or a smaller range)")
    return angles


class ToolAxisArm:
    """``arm`` with its tool free to turn about the TCP's z axis (``tcp`` (4, 4): the TCP
    in the fk frame) by each of ``angles`` (rad; module docstring)."""

    def __init__(self, arm: Arm, tcp: np.ndarray | None, angles: ArrayLike) -> None:
        self.base_arm = arm
        self.angles = np.array(angles, dtype=np.float64)
        self.angles.flags.writeable = False
        tcp = np.eye(4) if tcp is None else np.asarray(tcp, dtype=np.float64)
        #: Per angle: the fk frame's pose turned with the tool, as a right factor.
        self._turns = np.array([tcp @ _homogeneous_rz(a) @ invert_pose(tcp)
                                for a in self.angles])
        samples, k = len(self.angles), arm.n_branches
        self.n_branches = k * samples
        self.branch_labels = tuple(f"{label}/tool{math.degrees(a):+g}"
                                   for label in arm.branch_labels for a in self.angles)
        self.branch_closed_form = np.repeat(arm.branch_closed_form, samples)
        self.branch_closed_form.flags.writeable = False
        #: Per branch: its tool angle (rad).
        self.branch_angles = np.tile(self.angles, k)
        self.branch_angles.flags.writeable = False
        #: No turn copies among branch × angle (each angle is its own configuration).
        self.turn_windows: tuple = ()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.base_arm, name)

    def branch_pose(self, pose: np.ndarray, branch: int) -> np.ndarray:
        """The fk frame's pose branch ``branch`` reaches for waypoint ``pose`` (4, 4)."""
        return np.asarray(pose) @ self._turns[branch % len(self.angles)]

    def _turned(self, pose: ArrayLike) -> np.ndarray:
        """(…, S, 4, 4): ``pose`` (…, 4, 4) turned by every angle."""
        return np.asarray(pose, dtype=np.float64)[..., None, :, :] @ self._turns

    def ik(self, pose: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(…, K·S, dof) and (…, K·S): the arm's IK of each turned pose, branch-major."""
        q, ok = self.base_arm.ik(self._turned(pose))  # (…, S, K, dof), (…, S, K)
        q, ok = np.swapaxes(q, -3, -2), np.swapaxes(ok, -2, -1)  # (…, K, S, …)
        shape = (*q.shape[:-3], self.n_branches)
        return q.reshape(*shape, q.shape[-1]), ok.reshape(shape)

    def reaches(self, pose: ArrayLike) -> np.ndarray:
        """(…,) bool: some branch reaches ``pose`` at some angle, the limits aside."""
        return np.asarray(np.asarray(self.base_arm.reaches(self._turned(pose))).any(axis=-1))


def _homogeneous_rz(angle: float) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rot_z(angle)
    return out
