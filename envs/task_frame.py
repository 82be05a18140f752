"""The frame tasks speak in: poses in the cell, of the tool's TCP.

An arm's kinematics answer for its ``fk`` frame (the flange, or the papers' wrist centre)
in its base frame. A job is given in the cell (a scene file's world, or a built-in cell
with the arm's base placed in it) and for the tool's TCP. :class:`TaskFrame` maps between
the two: ``fk = base_from_cell · task_pose · inv(tcp)``. :class:`FramedArm` is the arm seen
from the task frame (its ``fk`` and ``ik`` take and give task-frame poses), so every task
generator works in the cell with any tool, without knowing about either.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import Arm


def _invert(pose: np.ndarray) -> np.ndarray:
    inverse = np.eye(4)
    inverse[:3, :3] = pose[:3, :3].T
    inverse[:3, 3] = -(pose[:3, :3].T @ pose[:3, 3])
    return inverse


class TaskFrame:
    """``cell_from_base`` (4, 4): the arm's base in the cell; ``tcp`` (4, 4): the TCP in
    the fk frame. Identity both: task poses are fk poses (every built-in id)."""

    def __init__(self, cell_from_base: np.ndarray | None = None,
                 tcp: np.ndarray | None = None) -> None:
        self.cell_from_base = np.eye(4) if cell_from_base is None else np.array(cell_from_base)
        self.tcp = np.eye(4) if tcp is None else np.array(tcp)
        self._base_from_cell = _invert(self.cell_from_base)
        self._fk_from_tcp = _invert(self.tcp)
        self.identity = bool(np.array_equal(self.cell_from_base, np.eye(4))
                             and np.array_equal(self.tcp, np.eye(4)))

    def to_fk(self, poses: ArrayLike) -> np.ndarray:
        """Task poses (…, 4, 4) as poses of the fk frame in the base frame."""
        if self.identity:
            return np.asarray(poses, dtype=np.float64)
        return self._base_from_cell @ np.asarray(poses, dtype=np.float64) @ self._fk_from_tcp

    def from_fk(self, poses: ArrayLike) -> np.ndarray:
        """Poses of the fk frame in the base frame (…, 4, 4) as task poses."""
        if self.identity:
            return np.asarray(poses, dtype=np.float64)
        return self.cell_from_base @ np.asarray(poses, dtype=np.float64) @ self.tcp


class FramedArm:
    """``arm`` seen from a :class:`TaskFrame`: ``fk`` gives task poses, ``ik`` takes them;
    everything else is the arm's own."""

    def __init__(self, arm: Arm, frame: TaskFrame) -> None:
        self.arm, self.frame = arm, frame

    def __getattr__(self, name: str) -> Any:
        return getattr(self.arm, name)

    def fk(self, q: ArrayLike) -> np.ndarray:
        return self.frame.from_fk(self.arm.fk(q))

    def positions(self, q: ArrayLike) -> np.ndarray:
        return self.fk(q)[..., :3, 3]

    def ik(self, pose: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        return self.arm.ik(self.frame.to_fk(pose))

    def reaches(self, pose: ArrayLike) -> np.ndarray:
        return self.arm.reaches(self.frame.to_fk(pose))

    def limit_overshoot(self, pose: ArrayLike) -> tuple[int, int, float, float] | None:
        return self.arm.limit_overshoot(self.frame.to_fk(pose))
