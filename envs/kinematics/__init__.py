"""Closed-form kinematics of the papers' arms and of real industrial arms (the OPW family,
Universal Robots): no RNG, no state. FK in numpy; IK as one scalar kernel per arm behind
one driver, compiled with numba on the first IK call (cached on disk; ``compiled.py``),
interpreted where numba is missing.

Contract (``arm.Arm``; every arm is held to it by ``tests/envs/kinematics/test_arms.py``):
``make_arm(name, **params)`` returns a frozen arm with ``fk(q) -> (…, 4, 4)`` and
``ik(pose) -> (Q (…, K, dof), ok (…, K))``.
"""

from __future__ import annotations

from typing import Any

from .anthropomorphic import AnthropomorphicArm
from .arm import LIMIT_TOL, Arm
from .cartesian import CartesianArm
from .cylindrical import CylindricalArm
from .cylindrical4 import Cylindrical4Arm
from .dual import DualPprPrrArm, DualRrpRppArm, DualRrrPppArm
from .frames import frenet_pose, frenet_rotation, pose_from_points
from .opw import AbbIrb2400, AbbIrb2600, AbbIrb4600, KukaKr6R700, OpwArm
from .rod import RodMechanism
from .spherical import SphericalArm
from .ur import Ur5e, Ur10e, UrArm

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
        OpwArm,
        KukaKr6R700,
        AbbIrb2400,
        AbbIrb2600,
        AbbIrb4600,
        UrArm,
        Ur5e,
        Ur10e,
    )
}

ARM_NAMES: tuple[str, ...] = tuple(_ARM_CLASSES)
#: The arms of the seeds (papers): closed-form branches only, limits within [−π, π].
SEED_ARM_NAMES: tuple[str, ...] = ARM_NAMES[:9]
#: Real industrial arms: data-sheet parameters and limits, turn branches.
INDUSTRIAL_ARM_NAMES: tuple[str, ...] = ARM_NAMES[9:]


def make_arm(name: str, **params: Any) -> Arm:
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
    "INDUSTRIAL_ARM_NAMES",
    "LIMIT_TOL",
    "SEED_ARM_NAMES",
    "Arm",
    "frenet_pose",
    "frenet_rotation",
    "make_arm",
    "pose_from_points",
]
