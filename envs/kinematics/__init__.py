"""Closed-form kinematics of the papers' arms: pure numpy, no I/O, no RNG, no state.

Contract (see ARCHITECTURE.md): ``make_arm(name, **params)`` returns a frozen arm with
``fk(q) -> (…, 4, 4)`` and ``ik(pose) -> (Q (…, K, dof), ok (…, K))``.
"""

from __future__ import annotations

from .anthropomorphic import AnthropomorphicArm
from .arm import LIMIT_TOL, Arm
from .cartesian import CartesianArm
from .cylindrical import CylindricalArm
from .cylindrical4 import Cylindrical4Arm
from .dual import DualPprPrrArm, DualRrpRppArm, DualRrrPppArm
from .frames import frenet_pose, frenet_rotation, pose_from_points
from .rod import RodMechanism
from .spherical import SphericalArm

_ARM_CLASSES: dict[str, type[Arm]] = {
    cls.name: cls
    for cls in (
        CartesianArm,
        CylindricalArm,
        SphericalArm,
        AnthropomorphicArm,
        Cylindrical4Arm,
        DualRrpRppArm,
        DualRrrPppArm,
        DualPprPrrArm,
        RodMechanism,
    )
}

ARM_NAMES: tuple[str, ...] = tuple(_ARM_CLASSES)


def make_arm(name: str, **params) -> Arm:
    """The arm ``name`` with its documented defaults, overridden by ``params``."""
    try:
        cls = _ARM_CLASSES[name]
    except KeyError:
        raise ValueError(f"unknown arm {name!r}; choose one of {', '.join(ARM_NAMES)}") from None
    try:
        return cls(**params)
    except TypeError as exc:
        raise ValueError(f"bad parameters for arm {name!r}: {exc}") from None


__all__ = [
    "ARM_NAMES",
    "LIMIT_TOL",
    "Arm",
    "frenet_pose",
    "frenet_rotation",
    "make_arm",
    "pose_from_points",
]
