"""A free tool axis: a round tool (a spindle, a deburring burr, a welding torch) does its
job whatever its rotation about its own axis, so every pose may be reached turned about
the TCP's z axis by any of a set of sampled angles; and where the process allows (a
**tilt cone**), with that axis tilted by up to a cone angle in any direction.

A sample's orientation change is Tilt(α, φ)·Rz(θ) in the TCP frame: the spin θ about the
tool's axis, then the axis tilted by α about the TCP-frame axis (cos φ, sin φ, 0), i.e.
Rz(φ)·Rx(α)·Rz(−φ). Tilts are sampled (:func:`tilt_directions`) at 0 and every multiple
of the tilt step up to the cone, each at azimuths no more than the step apart.

:class:`ToolAxisArm` wraps an arm: its branches are the arm's branches × the samples
(branch b, sample s is branch ``b·S + s``), the configuration of a branch is the arm's
closed-form branch (the tool's rotation is no reconfiguration), and its IK solves each
pose turned by each sample. Everything else (forward kinematics, limits, joint names) is
the arm's own, so the env, the planners and the DP price and plan over the larger ladder
unchanged: the DP stays exact over branch × angle. Pure numpy; no state.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.rotations import invert_pose, rot_x, rot_z

#: The most angles a tool axis may be sampled at, and the most orientations in all.
MAX_ANGLES = 73
MAX_SAMPLES = 73


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


def tilt_directions(cone: float, step: float) -> np.ndarray:
    """(D, 2) the sampled tilts (α, φ) rad: (0, 0) first, then for every multiple α of
    ``step`` up to ``cone`` the azimuths φ = 2πj/n with n = max(3, ⌈2π·sin α / step⌉), so
    neighbouring tilted axes lie at most about a step apart. ``ValueError`` for a cone
    outside [0, π/2] or a step that is not a positive angle."""
    cone, step = float(cone), float(step)
    if not (math.isfinite(cone) and 0.0 <= cone <= math.pi / 2):
        raise ValueError(f"tool tilt cone must lie in [0, π/2] rad, got {cone!r}")
    if not (math.isfinite(step) and step > 0.0):
        raise ValueError(f"tool tilt step must be a positive angle, got {step!r}")
    out = [(0.0, 0.0)]
    for k in range(1, math.floor(cone / step + 1e-9) + 1):
        tilt = k * step
        count = max(3, math.ceil(2.0 * math.pi * math.sin(tilt) / step - 1e-9))
        out += [(tilt, 2.0 * math.pi * j / count) for j in range(count)]
    return np.array(out)


class ToolAxisArm:
    """``arm`` with its tool free to turn about the TCP's z axis (``tcp`` (4, 4): the TCP
    in the fk frame) by each of ``angles`` (rad), and, with ``tilts`` ((D, 2) (α, φ) from
    :func:`tilt_directions`), its axis tilted by each (module docstring). Samples run
    tilt-major: sample s is angle ``s % len(angles)`` of tilt ``s // len(angles)``."""

    def __init__(self, arm: Arm, tcp: np.ndarray | None, angles: ArrayLike,
                 tilts: ArrayLike | None = None) -> None:
        self.base_arm = arm
        spins = np.array(angles, dtype=np.float64)
        tilts = np.zeros((1, 2)) if tilts is None else np.array(tilts, dtype=np.float64)
        if len(spins) * len(tilts) > MAX_SAMPLES:
            raise ValueError(f"the free tool axis samples {len(spins)} angles × {len(tilts)} "
                             f"tilts = {len(spins) * len(tilts)} orientations; at most "
                             f"{MAX_SAMPLES} (larger steps, or smaller ranges)")
        #: Per sample: its spin about the tool's axis, its tilt and the tilt's azimuth (rad).
        self.angles = np.tile(spins, len(tilts))
        self.tilts = np.repeat(tilts[:, 0], len(spins))
        self.azimuths = np.repeat(tilts[:, 1], len(spins))
        for array in (self.angles, self.tilts, self.azimuths):
            array.flags.writeable = False
        tcp = np.eye(4) if tcp is None else np.asarray(tcp, dtype=np.float64)
        #: Per sample: the fk frame's pose turned with the tool, as a right factor.
        self._turns = np.array([
            tcp @ _homogeneous(rot_z(azimuth) @ rot_x(tilt) @ rot_z(-azimuth) @ rot_z(spin))
            @ invert_pose(tcp)
            for spin, tilt, azimuth in zip(self.angles, self.tilts, self.azimuths, strict=True)])
        samples, k = len(self.angles), arm.n_branches
        self.n_branches = k * samples
        self.branch_labels = tuple(
            f"{label}/tool{math.degrees(a):+g}"
            + (f"/tilt{math.degrees(t):g}@{math.degrees(z):g}" if t > 0.0 else "")
            for label in arm.branch_labels
            for a, t, z in zip(self.angles, self.tilts, self.azimuths, strict=True))
        self.branch_closed_form = np.repeat(arm.branch_closed_form, samples)
        self.branch_closed_form.flags.writeable = False
        #: Per branch: its tool angle, tilt and tilt azimuth (rad).
        self.branch_angles = np.tile(self.angles, k)
        self.branch_tilts = np.tile(self.tilts, k)
        self.branch_azimuths = np.tile(self.azimuths, k)
        for array in (self.branch_angles, self.branch_tilts, self.branch_azimuths):
            array.flags.writeable = False
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


def _homogeneous(rotation: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rotation
    return out
