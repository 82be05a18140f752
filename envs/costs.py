"""The cost of moving between two configurations: travel, time and their reward weights.

Pure numpy: the environment, the analytic baselines and the DP oracle all price a
transition with the same :class:`TransitionCost` (``envs/moves.py`` turns it into the
reward terms −travel_weight·travel and −time_weight·time), so an oracle's return is
exactly what the env would pay.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.speeds import rated_speeds

#: Default joint speed limits: rad/s for revolute joints, m/s for prismatic ones (typical
#: of mid-size industrial arms' slower axes; override per joint with ``joint_speeds``, or
#: take a real arm's data sheet with ``joint_speeds="rated"``).
DEFAULT_REVOLUTE_SPEED = 1.5
DEFAULT_PRISMATIC_SPEED = 0.5


@dataclass(frozen=True, eq=False)
class TransitionCost:
    """Travel and time of the linear joint-space move q0 → q1, and their reward weights.

    travel = Σ_j w_j·s_j·|Δq_j|, with s_j = 1 for revolute joints and ``prismatic_scale``
    (rad per m) for prismatic ones, so travel is in rad-equivalents (the paper's Σ|Δφ|);
    time = max_j |Δq_j| / v_j (s), all joints starting and stopping together.
    """

    weights: np.ndarray  # (dof,) w_j · s_j
    speeds: np.ndarray  # (dof,) v_j
    travel_weight: float
    time_weight: float

    @classmethod
    def for_arm(
        cls,
        arm: Arm,
        *,
        travel_weight: float = 1.0,
        time_weight: float = 0.0,
        prismatic_scale: float = 1.0,
        joint_weights: ArrayLike | None = None,
        joint_speeds: ArrayLike | str | None = None,
    ) -> TransitionCost:
        revolute = arm.revolute_mask
        weights = _per_joint(joint_weights, arm.dof, 1.0, "joint_weights")
        scale = _non_negative(prismatic_scale, "prismatic_scale")
        weights = weights * np.where(revolute, 1.0, scale)
        default_speeds = np.where(revolute, DEFAULT_REVOLUTE_SPEED, DEFAULT_PRISMATIC_SPEED)
        if isinstance(joint_speeds, str):
            joint_speeds = _rated(arm, joint_speeds)
        speeds = _per_joint(joint_speeds, arm.dof, default_speeds, "joint_speeds")
        if np.any(speeds <= 0.0):
            raise ValueError("joint_speeds must be positive")
        return cls(
            weights=weights,
            speeds=speeds,
            travel_weight=_non_negative(travel_weight, "travel_weight"),
            time_weight=_non_negative(time_weight, "time_weight"),
        )

    def travel(self, q0: ArrayLike, q1: ArrayLike) -> np.ndarray:
        """(…,) weighted joint travel, broadcasting q0 and q1 (…, dof).

        A sum over the last axis rather than a matrix product: BLAS sums a row in an order
        that depends on the batch shape, and one move must cost the same to the last bit
        whether it is priced alone (``step``) or with others (``edge_rewards``, planners).
        """
        return (np.abs(np.asarray(q1) - np.asarray(q0)) * self.weights).sum(axis=-1)

    def time(self, q0: ArrayLike, q1: ArrayLike) -> np.ndarray:
        """(…,) move time with every joint at its speed limit, the slowest setting the pace."""
        return np.max(np.abs(np.asarray(q1) - np.asarray(q0)) / self.speeds, axis=-1)


def _rated(arm: Arm, text: str) -> np.ndarray:
    """The arm's data-sheet speeds for ``joint_speeds="rated"``."""
    if text != "rated":
        raise ValueError(f'joint_speeds must be a list of speeds or "rated", got {text!r}')
    speeds = rated_speeds(getattr(arm, "base_arm", arm))
    if speeds is None:
        raise ValueError(f'joint_speeds="rated": the arm {arm.name} has no data-sheet speeds '
                         "(envs/kinematics/speeds.py); give one speed per joint")
    return speeds


def _non_negative(value: float, name: str) -> float:
    value = float(value)
    if not np.isfinite(value) or value < 0.0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value}")
    return value


def _per_joint(values: ArrayLike | None, dof: int, default: ArrayLike, name: str) -> np.ndarray:
    if values is None:
        return np.broadcast_to(np.asarray(default, dtype=np.float64), (dof,)).copy()
    array = np.asarray(values, dtype=np.float64)
    if array.shape != (dof,):
        raise ValueError(f"{name} must have {dof} entries (one per joint), got {array.shape}")
    if not np.all(np.isfinite(array)) or np.any(array < 0.0):
        raise ValueError(f"{name} must be finite and >= 0")
    return array
