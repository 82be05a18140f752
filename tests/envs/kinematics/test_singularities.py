"""Singularity margins (envs/kinematics/singularities.py) against the Jacobian: where a
margin is zero the arm loses a degree of freedom (the smallest singular value of a
finite-difference Jacobian of ``arm.fk`` vanishes), and away from every margin it does
not. Singular configurations are built here from the families' geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.singularities import (
    has_singularity_rules,
    singularity_margins,
)

ARMS = ("kuka_kr6_r700", "abb_irb2400", "abb_irb4600", "ur5e")


def _smallest_singular_value(arm, q: np.ndarray, h: float = 1e-6) -> float:
    """σ_min of the 6 × 6 Jacobian of the flange's position and orientation (central
    differences of ``arm.fk``; the rotation's change as the axial vector of ΔR·Rᵀ)."""
    columns = []
    for j in range(6):
        step = np.zeros(6)
        step[j] = h
        ahead, behind = arm.fk(q + step), arm.fk(q - step)
        velocity = (ahead[:3, 3] - behind[:3, 3]) / (2 * h)
        spin = (ahead[:3, :3] - behind[:3, :3]) @ arm.fk(q)[:3, :3].T / (2 * h)
        omega = 0.5 * np.array([spin[2, 1] - spin[1, 2], spin[0, 2] - spin[2, 0],
                                spin[1, 0] - spin[0, 1]])
        columns.append(np.concatenate([velocity, omega]))
    return float(np.linalg.svd(np.array(columns).T, compute_uv=False)[-1])


def _kinematic(arm, theta: np.ndarray) -> np.ndarray:
    """Joint values of kinematic angles θ (OPW: (θ + offset)·sign; UR: θ itself)."""
    if arm.name.startswith("ur"):
        return np.asarray(theta, dtype=np.float64)
    return arm.joints_from_angles(theta)


def _elbow_stretched(arm) -> float:
    """The θ3 at which the forearm is stretched along the upper arm."""
    return 0.0 if arm.name.startswith("ur") else -math.atan2(arm.a2, arm.c3)


@pytest.mark.parametrize("name", ARMS)
def test_zero_margins_are_where_the_jacobian_loses_rank(name):
    arm = make_arm(name)
    rng = np.random.default_rng(3)
    base = rng.uniform(-0.8, 0.8, size=6)
    wrist = base.copy()
    wrist[4] = 0.0
    elbow = base.copy()
    elbow[2] = _elbow_stretched(arm)
    for theta, which in ((wrist, "wrist"), (elbow, "elbow")):
        q = _kinematic(arm, theta)
        margins = singularity_margins(arm, q)
        assert getattr(margins, which) == pytest.approx(0.0, abs=1e-12)
        assert _smallest_singular_value(arm, q) < 1e-6
    # The shoulder: a pose whose wrist point stands where the two shoulder solutions meet
    # (the j1 axis itself for OPW arms with b = 0; a distance d4 from it for UR), the tool
    # turned so that some branch lies inside the limits.
    offset = arm.d4 if name == "ur5e" else arm.b
    shoulder = arm.d1 if name == "ur5e" else arm.c1
    length = arm.d6 if name == "ur5e" else arm.c4
    tries = [(rise, pitch) for rise in (0.4, 0.8, 1.2) for pitch in (90, 60, 120, 45, 135, 180)]
    for rise, pitch in tries:
        c, s = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
        pose = np.eye(4)
        pose[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
        pose[:3, 3] = np.array([0.0, offset, shoulder + rise]) + length * pose[:3, 2]
        candidates, valid = arm.ik(pose)
        if valid.any():
            break
    assert valid.any()
    for q in candidates[valid][:4]:
        assert singularity_margins(arm, q).shoulder == pytest.approx(0.0, abs=1e-6)
        assert _smallest_singular_value(arm, q) < 1e-4


@pytest.mark.parametrize("name", ARMS)
def test_away_from_every_margin_the_arm_keeps_its_freedom(name):
    arm = make_arm(name)
    rng = np.random.default_rng(7)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(400, 6))
    margins = singularity_margins(arm, q)
    clear = ((margins.wrist > math.radians(15)) & (margins.elbow > math.radians(15))
             & (margins.shoulder > 0.1))
    assert clear.sum() > 20
    for row in q[clear][:20]:
        assert _smallest_singular_value(arm, row) > 1e-3


def test_margins_fold_to_the_nearer_multiple_of_pi_and_nan_stays_nan():
    arm = make_arm("ur5e")
    q = np.zeros((2, 4, 6))
    q[..., 4] = [math.radians(10), math.radians(170), math.radians(-100), np.pi / 2]
    q[1, 3, 0] = np.nan  # a branch that does not exist
    margins = singularity_margins(arm, q)
    np.testing.assert_allclose(np.degrees(margins.wrist[0]), [10, 10, 80, 90], atol=1e-9)
    np.testing.assert_array_equal(margins.wrist[1, :3], margins.wrist[0, :3])
    for values in (margins.wrist, margins.elbow, margins.shoulder):
        assert np.isnan(values[1, 3]) and np.isfinite(values[0]).all()


def test_only_the_opw_and_ur_families_have_rules():
    assert has_singularity_rules(make_arm("kuka_kr6_r700"))
    assert has_singularity_rules(make_arm("ur10e"))
    arm = make_arm("anthropomorphic")
    assert not has_singularity_rules(arm)
    with pytest.raises(ValueError, match="no singularity rules"):
        singularity_margins(arm, np.zeros(6))
