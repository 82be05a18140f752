"""Rated joint speeds of the real arms: what their data sheets give, frozen.

A move's time (``envs/costs.py``) is max_j |Δq_j| / v_j; with these v_j it is the time the
controller needs at 100 % override if acceleration were instant — a lower bound on the
real move, and the same bound for every planner compared. The paper arms have no data
sheet and keep the generic defaults.

Values in degrees per second as printed; :func:`rated_speeds` returns rad/s.
"""

from __future__ import annotations

import math

import numpy as np

from .arm import Arm

#: Degrees per second per joint, with where each row comes from.
RATED_SPEEDS_DEG: dict[str, tuple[float, ...]] = {
    # KR 6 R700 sixx data sheet, as in ROS-Industrial kuka_kr6_support
    # (kr6r700sixx_macro.xacro, joint velocity limits).
    "kuka_kr6_r700": (360.0, 300.0, 360.0, 381.0, 388.0, 615.0),
    # IRB 2400/10 product specification, as in abb_irb2400_support (irb2400_macro.xacro:
    # 2.618, 6.2832 and 7.854 rad/s).
    "abb_irb2400": (150.0, 150.0, 150.0, 360.0, 360.0, 450.0),
    # IRB 2600-12/1.65 product specification, as in abb_irb2600_support
    # (irb2600_12_165_macro.xacro: 3.054, 6.283 and 8.727 rad/s).
    "abb_irb2600": (175.0, 175.0, 175.0, 360.0, 360.0, 500.0),
    # IRB 4600-60/2.05 product specification, as in abb_irb4600_support
    # (irb4600_60_205_macro.xacro: 3.054, 4.363 and 6.283 rad/s).
    "abb_irb4600": (175.0, 175.0, 175.0, 250.0, 250.0, 360.0),
    # UR5e: 180 °/s on every joint (UR e-Series data sheet; ur_description
    # config/ur5e/joint_limits.yaml, max_velocity π).
    "ur5e": (180.0, 180.0, 180.0, 180.0, 180.0, 180.0),
    # UR10e: base and shoulder 120 °/s, the others 180 °/s (UR e-Series data sheet;
    # ur_description config/ur10e/joint_limits.yaml, 2.0944 and π).
    "ur10e": (120.0, 120.0, 180.0, 180.0, 180.0, 180.0),
}


def rated_speeds(arm: Arm) -> np.ndarray | None:
    """(dof,) the arm's rated joint speeds in rad/s, or None if it has no data sheet."""
    degrees = RATED_SPEEDS_DEG.get(arm.name)
    if degrees is None:
        return None
    return np.array([math.radians(v) for v in degrees], dtype=np.float64)
