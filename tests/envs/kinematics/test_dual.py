"""The three two-arm systems of Vorob'ev (2020): frames against the paper, all-branch IK,
completeness against a numerical solver, and the documented singular conventions."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import least_squares

from ikbranch_gym.envs.kinematics.dual import (
    DualPprPrrArm,
    DualRrpRppArm,
    DualRrrPppArm,
    solve_zxz,
)
from ikbranch_gym.envs.kinematics.rotations import rot_x, rot_z

ARM_CLASSES = (DualRrpRppArm, DualRrrPppArm, DualPprPrrArm)
#: Index of the middle Z–X–Z angle, whose sign names the branch (``phi1+`` …).
MIDDLE_JOINT = {"dual_rrp_rpp": 0, "dual_rrr_ppp": 1, "dual_ppr_prr": 4}
FK_TOL = 1e-9
DEG = np.pi / 180.0


@pytest.fixture(params=ARM_CLASSES, ids=lambda cls: cls.name)
def arm(request):
    return request.param()


def sample(arm, n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(n, arm.dof))


def joint_distance(arm, q_a, q_b):
    delta = np.abs(np.asarray(q_a) - np.asarray(q_b))
    rev = arm.revolute_mask
    delta[..., rev] = np.abs(np.remainder(delta[..., rev] + np.pi, 2 * np.pi) - np.pi)
    return delta.max(axis=-1)


def assert_valid_branches_reproduce(arm, pose, solutions, valid):
    assert np.all(np.isnan(solutions[~valid]))
    assert np.all(np.isfinite(solutions[valid]))
    assert np.all(arm.within_limits(solutions[valid]))
    reposed = arm.fk(np.where(valid[..., None], solutions, arm.home))
    error = np.abs(reposed - pose[..., None, :, :]).max(axis=(-1, -2))
    assert np.all(error[valid] < FK_TOL), error[valid].max()


def quiet_ik(arm, pose):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return arm.ik(pose)


# ----------------------------------------------------------------------------- contract
def test_contract_attributes(arm):
    assert arm.dof == 6 and arm.n_branches == 2
    assert len(arm.joint_names) == len(arm.joint_types) == 6
    assert arm.branch_labels[0].endswith("+") and arm.branch_labels[1].endswith("-")
    assert arm.within_limits(arm.home)
    assert np.all(np.abs(arm.joint_limits[arm.revolute_mask]) <= np.pi)
    pose = arm.fk(arm.home)
    assert pose.shape == (4, 4) and np.all(np.isfinite(pose))
    solutions, valid = arm.ik(pose)
    assert valid.any(), "home must be reachable from its own pose"
    assert np.any(joint_distance(arm, solutions[valid], arm.home) < 1e-9)


def test_joint_order_follows_the_paper():
    assert DualRrpRppArm.joint_names == ("phi1", "phi2", "s3", "phi6", "s5", "s4")
    assert DualRrrPppArm.joint_names == ("phi1", "phi2", "phi3", "s4", "s5", "s6")
    assert DualPprPrrArm.joint_names == ("s1", "s2", "phi3", "s4", "phi5", "phi6")
    for cls in ARM_CLASSES:
        kinds = "".join("R" if t == "revolute" else "P" for t in cls.joint_types)
        assert sorted(kinds) == sorted("".join(cls.name.split("_")[1:]).upper())
        assert kinds.count("R") == 3  # the paper: at least three revolute pairs in total


@pytest.mark.parametrize(
    ("cls", "bad"),
    [
        (DualRrpRppArm, {"a0": 0.0}),
        (DualRrpRppArm, {"l1": -0.1}),
        (DualRrrPppArm, {"l2": 0.0}),
        (DualPprPrrArm, {"l5": -1.0}),
        (DualRrpRppArm, {"b0": np.nan}),
    ],
)
def test_impossible_dimensions_are_value_errors(cls, bad):
    with pytest.raises(ValueError):
        cls(**bad)


# ------------------------------------------------------------------ frames vs the paper
def test_rrp_rpp_frames_match_the_papers_equations():
    """Eqs. (2)=(5) and (3)=(6) with α = M43's rotation and (a, b, c) = C3 in frame 4.

    (5) is used with its lost sign restored ((1,2) = −sin φ2), (2) with (1,2) =
    α12 cos φ6 − α22 sin φ6 and (3,3) = α33.
    """
    arm = DualRrpRppArm()
    q = sample(arm, 200, seed=1)
    m34 = arm.fk(q)
    alpha = np.swapaxes(m34[:, :3, :3], -1, -2)
    a, b, c = np.einsum("nij,nj->ni", -alpha, m34[:, :3, 3]).T
    f1, f2, s3, f6, s5, s4 = q.T
    c1, c2, c6 = np.cos([f1, f2, f6])
    s1_, s2_, s6_ = np.sin([f1, f2, f6])
    eq2 = np.stack(
        [
            np.stack([alpha[:, 0, j] * c6 - alpha[:, 1, j] * s6_ for j in range(3)], -1),
            np.stack([alpha[:, 0, j] * s6_ + alpha[:, 1, j] * c6 for j in range(3)], -1),
            alpha[:, 2, :],
        ],
        -2,
    )
    eq5 = np.stack(
        [
            np.stack([c2, -s2_, 0 * c2], -1),
            np.stack([c1 * s2_, c1 * c2, -s1_], -1),
            np.stack([s1_ * s2_, s1_ * c2, c1], -1),
        ],
        -2,
    )
    np.testing.assert_allclose(eq2, eq5, atol=1e-12)
    b1 = arm.b0 + b
    eq3 = np.stack([(a + s4) * c6 - b1 * s6_, (a + s4) * s6_ + b1 * c6, c + s5], -1)
    eq6 = np.stack(
        [s3 * c2 + arm.a0, s3 * s2_ * c1 - arm.l1 * s1_, s3 * s2_ * s1_ + arm.l1 * c1], -1
    )
    np.testing.assert_allclose(eq3, eq6, atol=1e-12)


def test_rrr_ppp_frames_match_the_papers_equations():
    """Eqs. (8)/(9) = (10) with α = L03; (8) with the x sign restored, (10) with + c."""
    arm = DualRrrPppArm()
    q = sample(arm, 200, seed=2)
    m34 = arm.fk(q)
    alpha = np.swapaxes(m34[:, :3, :3], -1, -2)
    a, b, c = np.einsum("nij,nj->ni", -alpha, m34[:, :3, 3]).T
    f1, f2, f3, s4, s5, s6 = q.T
    c1, c2, c3 = np.cos([f1, f2, f3])
    s1, s2, s3 = np.sin([f1, f2, f3])
    eq9 = np.stack(
        [
            np.stack([c1 * c3 - s1 * c2 * s3, -c1 * s3 - s1 * c2 * c3, s1 * s2], -1),
            np.stack([s1 * c3 + c1 * c2 * s3, -s1 * s3 + c1 * c2 * c3, -c1 * s2], -1),
            np.stack([s2 * s3, s2 * c3, c2], -1),
        ],
        -2,
    )
    np.testing.assert_allclose(alpha, eq9, atol=1e-12)  # L03 via arm 2 is α (R4 = I)
    l1, l2, l3, h = arm.l1, arm.l2, arm.l3, arm.h
    u, v = l3 * c3 + l1, l3 * s3 * c2 - l2 * s2
    eq8 = np.stack([u * c1 - v * s1, u * s1 + v * c1, l3 * s3 * s2 + l2 * c2 + h], -1)
    eq10 = np.stack([s6 + a, s4 + arm.b0 + b, s5 + c + h], -1)
    np.testing.assert_allclose(eq8, eq10, atol=1e-12)


def test_ppr_prr_frames_match_the_papers_equations():
    """Eqs. (12)=(15) and (13)=(16), both as printed; the joints s4, φ6 are the equations'
    s6, φ4."""
    arm = DualPprPrrArm()
    q = sample(arm, 200, seed=3)
    m34 = arm.fk(q)
    alpha = m34[:, :3, :3]
    a, b, c = m34[:, :3, 3].T
    s1, s2, f3, lift, f5, f4 = q.T
    c3, c4, c5 = np.cos([f3, f4, f5])
    s3, s4, s5 = np.sin([f3, f4, f5])
    eq12 = np.stack(
        [
            np.stack([alpha[:, 0, j] * c3 - alpha[:, 1, j] * s3 for j in range(3)], -1),
            np.stack([alpha[:, 0, j] * s3 + alpha[:, 1, j] * c3 for j in range(3)], -1),
            alpha[:, 2, :],
        ],
        -2,
    )
    eq15 = np.stack(
        [
            np.stack([c4, -s4, 0 * c4], -1),
            np.stack([c5 * s4, c5 * c4, -s5], -1),
            np.stack([s5 * s4, s5 * c4, c5], -1),
        ],
        -2,
    )
    np.testing.assert_allclose(eq12, eq15, atol=1e-12)
    l1, l3, l4, l5 = arm.l1, arm.l3, arm.l4, arm.l5
    eq13 = np.stack([(a + l3) * c3 - b * s3 + s1, (a + l3) * s3 + b * c3 + s2, c + l1], -1)
    eq16 = np.stack([l4 * c4, l4 * s4 * c5 - l5 * s5, l4 * s4 * s5 + l5 * c5 + lift], -1)
    np.testing.assert_allclose(eq13, eq16, atol=1e-12)


# ---------------------------------------------------------- the printed solutions, checked
def test_printed_solutions_hold_only_after_correction():
    """The paper's closed forms against FK (see docs/seed003.md for each misprint)."""
    # RRP-RPP, eq. (7): φ2 = arccos(α31/α32) is wrong, the tangent is right.
    arm = DualRrpRppArm()
    q = np.array([20 * DEG, 160 * DEG, 0.6, 120 * DEG, 0.5, 0.5])
    alpha = arm.fk(q)[:3, :3].T
    assert np.arccos(alpha[2, 2]) == pytest.approx(q[0])
    assert abs(np.arccos(alpha[2, 0] / alpha[2, 1]) - q[1]) > 0.5
    assert np.arctan2(alpha[2, 0], alpha[2, 1]) == pytest.approx(q[1])
    # φ6 = arctg(α13/α23) needs the quadrant: sin φ6 = −α13 / sin φ1.
    assert abs(np.arctan(alpha[0, 2] / alpha[1, 2]) - q[3]) == pytest.approx(np.pi)
    assert np.arctan2(-alpha[0, 2], -alpha[1, 2]) == pytest.approx(q[3])

    # RRR-PPP: φ1 = arctg(α13/α23) has the wrong sign, φ3 = arctg(−α13/α23) is φ1's formula.
    arm = DualRrrPppArm()
    q = np.array([30 * DEG, 45 * DEG, 70 * DEG, -1.0, -0.3, 0.3])
    alpha = arm.fk(q)[:3, :3].T
    assert np.arctan(alpha[0, 2] / alpha[1, 2]) == pytest.approx(-q[0])
    assert np.arctan2(alpha[0, 2], -alpha[1, 2]) == pytest.approx(q[0])
    assert abs(np.arctan(-alpha[0, 2] / alpha[1, 2]) - q[2]) > 0.5
    assert np.arctan2(alpha[2, 0], alpha[2, 1]) == pytest.approx(q[2])

    # PPR-PRR, eq. (17): right up to the quadrants, s1, s2, s6 right as printed.
    arm = DualPprPrrArm()
    q = np.array([0.2, 0.0, 150 * DEG, 0.5, 45 * DEG, -120 * DEG])
    pose = arm.fk(q)
    alpha, (a, b, c) = pose[:3, :3], pose[:3, 3]
    f3, f5, f4 = q[2], q[4], q[5]
    assert abs(np.arctan(alpha[0, 2] / alpha[1, 2]) - f3) == pytest.approx(np.pi)
    assert np.arctan2(-alpha[0, 2], -alpha[1, 2]) == pytest.approx(f3)
    assert np.arctan2(alpha[2, 0], alpha[2, 1]) == pytest.approx(f4)
    l1, l3, l4, l5 = arm.l1, arm.l3, arm.l4, arm.l5
    s1 = l4 * np.cos(f4) - (a + l3) * np.cos(f3) + b * np.sin(f3)
    s2 = l4 * np.sin(f4) * np.cos(f5) - l5 * np.sin(f5) - (a + l3) * np.sin(f3) - b * np.cos(f3)
    s6 = (c + l1) - l4 * np.sin(f4) * np.sin(f5) - l5 * np.cos(f5)
    np.testing.assert_allclose([s1, s2, s6], q[[0, 1, 3]], atol=1e-12)


# ------------------------------------------------------------------------- round trips
def test_round_trip_on_random_configurations(arm):
    q = sample(arm, 1000, seed=20260)
    pose = arm.fk(q)
    solutions, valid = quiet_ik(arm, pose)
    assert solutions.shape == (1000, 2, 6) and valid.shape == (1000, 2)
    assert_valid_branches_reproduce(arm, pose, solutions, valid)
    distance = np.where(valid, joint_distance(arm, solutions, q[:, None, :]), np.inf)
    assert np.all(distance.min(axis=1) < 1e-7)


def test_branch_labels_name_the_sign_of_the_middle_angle(arm):
    q = sample(arm, 500, seed=11)
    solutions, valid = arm.ik(arm.fk(q))
    middle = solutions[..., MIDDLE_JOINT[arm.name]]
    assert np.all(middle[valid[:, 0], 0] >= 0.0)
    assert np.all(middle[valid[:, 1], 1] <= 0.0)
    both = valid.all(axis=1)
    assert both.sum() > 10, "the flipped branch should be reachable for a share of poses"
    # The two branches differ: the flip moves the middle angle to its negative.
    np.testing.assert_allclose(middle[both, 0], -middle[both, 1], atol=1e-9)


def test_solve_zxz_reproduces_rotations_including_singular_ones():
    rng = np.random.default_rng(4)
    a, c = rng.uniform(-np.pi, np.pi, (2, 400))
    b = np.concatenate(
        [
            rng.uniform(-np.pi, np.pi, 100),
            rng.uniform(-1e-9, 1e-9, 100),
            np.pi - rng.uniform(0, 1e-9, 100),
            np.zeros(100),
        ]
    )
    rotation = rot_z(a) @ rot_x(b) @ rot_z(c)
    solved = np.array([solve_zxz(r) for r in rotation])
    rebuilt = rot_z(solved[..., 0]) @ rot_x(solved[..., 1]) @ rot_z(solved[..., 2])
    assert np.abs(rebuilt - rotation[:, None]).max() < 1e-9
    assert np.all(solved[:, 0, 1] >= 0.0) and np.all(solved[:, 1, 1] <= 0.0)


# ------------------------------------------------------------------------ completeness
@pytest.mark.parametrize("cls", ARM_CLASSES, ids=lambda cls: cls.name)
def test_every_numerical_solution_is_a_returned_branch(cls):
    arm = cls()
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    rng = np.random.default_rng(77)
    targets = arm.fk(sample(arm, 10, seed=78))
    found, returned, matched = 0, 0, set()
    for index, pose in enumerate(targets):
        solutions, valid = arm.ik(pose)
        returned += valid.sum()

        def residual(x, pose=pose):
            return (arm.fk(x) - pose)[:3].ravel()

        def jacobian(x, pose=pose):
            # Forward differences with scipy's relative step, √eps·max(1, |x|) (backwards
            # where it would leave the upper bound), every point in one fk call: the
            # residual's Python overhead, not its arithmetic, is what the fits cost.
            step = np.sqrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(x))
            step = np.where(x + step > upper, -step, step)
            points = np.vstack([x, x + np.diag(step)])
            values = (arm.fk(points) - pose)[:, :3].reshape(len(points), -1)
            return ((values[1:] - values[0]) / step[:, None]).T

        for start in rng.uniform(lower, upper, size=(30, arm.dof)):
            fit = least_squares(
                residual, start, jac=jacobian, bounds=(lower, upper), xtol=1e-15, ftol=1e-15,
                gtol=1e-15
            )
            if np.abs(fit.fun).max() > 1e-10:
                continue  # a local minimum, not a solution
            found += 1
            distance = np.where(valid, joint_distance(arm, solutions, fit.x), np.inf)
            assert distance.min() < 1e-6, (fit.x, solutions)
            matched.add((index, int(np.argmin(distance))))
    assert found >= 20, "the numerical solver should converge from some starts"
    # The converse, as a sanity check of the search: it meets (nearly) every returned branch.
    assert len(matched) >= 0.9 * returned


# ------------------------------------------------------------- singular configurations
@pytest.mark.parametrize("phi1", [0.0, np.pi, 1e-13, np.pi - 1e-13, 1e-9])
@pytest.mark.parametrize("seed", range(5))
def test_rrp_rpp_near_and_at_the_coaxial_singularity(phi1, seed):
    arm = DualRrpRppArm()
    q = sample(arm, 1, seed=seed)[0]
    q[0] = phi1
    pose = arm.fk(q)
    solutions, valid = quiet_ik(arm, pose)
    assert_valid_branches_reproduce(arm, pose, solutions, valid)
    np.testing.assert_array_equal(solutions, arm.ik(pose.copy())[0])  # deterministic


@pytest.mark.parametrize("seed", range(20))
def test_rrp_rpp_coaxial_convention_puts_s3_at_mid_stroke(seed):
    arm = DualRrpRppArm()
    q = sample(arm, 1, seed=100 + seed)[0]
    q[0] = 0.0 if seed % 2 else np.pi
    if seed % 4 == 0:
        q[3] = q[1] if q[0] == 0.0 else -q[1]  # R34 = I or Rx(π): s3, s4 on one line
    pose = arm.fk(q)
    solutions, valid = quiet_ik(arm, pose)
    assert_valid_branches_reproduce(arm, pose, solutions, valid)
    rotation, t = pose[:3, :3], pose[:3, 3]
    s3_mid = arm.joint_limits[2].mean()
    # Mid-stroke is attainable iff |sin φ6| ≤ 1 in the lateral equation (docs/seed003.md).
    sine = ((rotation.T @ t)[1] - arm.b0 + s3_mid * rotation[0, 1]) / arm.a0
    if abs(sine) <= 1.0:
        np.testing.assert_allclose(solutions[valid, 2], s3_mid, atol=1e-12)
    assert np.all(np.abs(np.sin(solutions[valid, 0])) < 1e-12)


def test_rrp_rpp_identity_pose_is_solved():
    arm = DualRrpRppArm()
    q = np.array([0.0, 0.3, 0.5, 0.3, 0.4, 0.6])
    pose = arm.fk(q)
    np.testing.assert_allclose(pose[:3, :3], np.eye(3), atol=1e-15)
    solutions, valid = quiet_ik(arm, pose)
    assert valid.any()
    assert_valid_branches_reproduce(arm, pose, solutions, valid)


def test_rrp_rpp_slide_in_the_plane_of_the_other_slides():
    """x3 ⟂ y4 (φ2 = φ6 = 0): s3 is free if the lateral offset matches, else impossible."""
    arm = DualRrpRppArm()
    q = np.array([0.7, 0.0, 0.5, 0.0, 0.4, 0.6])
    pose = arm.fk(q)
    solutions, valid = quiet_ik(arm, pose)
    assert valid[0] and not valid[1]
    assert_valid_branches_reproduce(arm, pose, solutions, valid)
    assert solutions[0, 2] == pytest.approx(arm.joint_limits[2].mean())
    shifted = pose.copy()
    shifted[:3, 3] += 0.05 * pose[:3, :3] @ (0.0, 1.0, 0.0)  # off the lateral offset b0
    solutions, valid = quiet_ik(arm, shifted)
    assert not valid.any() and np.all(np.isnan(solutions))


@pytest.mark.parametrize("cls", [DualRrrPppArm, DualPprPrrArm], ids=lambda cls: cls.name)
@pytest.mark.parametrize("flip", [False, True])
def test_even_split_at_the_zxz_singularity(cls, flip):
    arm = cls(
        joint_limits=[
            (-np.pi, np.pi) if kind == "revolute" else limits
            for kind, limits in zip(cls.joint_types, cls().joint_limits, strict=True)
        ]
    )
    middle = MIDDLE_JOINT[arm.name]
    for seed in range(10):
        q = sample(arm, 1, seed=seed)[0]
        q[middle] = np.pi if flip else 0.0
        pose = arm.fk(q)
        solutions, valid = quiet_ik(arm, pose)
        assert_valid_branches_reproduce(arm, pose, solutions, valid)
        if not valid.all():
            continue
        np.testing.assert_allclose(joint_distance(arm, solutions[0], solutions[1]), 0.0, atol=1e-12)
        if arm.name == "dual_rrr_ppp":  # φ1 = ±φ3
            first, last = solutions[0, 0], solutions[0, 2]
        else:  # φ6 = ∓φ3
            first, last = solutions[0, 5], -solutions[0, 2]
        expected = -last if flip else last
        assert abs(np.remainder(first - expected + np.pi, 2 * np.pi) - np.pi) < 1e-9


# ------------------------------------------------------------------------- bad input
def test_bad_input_is_a_value_error(arm):
    pose = arm.fk(arm.home)
    with pytest.raises(ValueError):
        arm.ik(np.where(np.eye(4, dtype=bool), np.nan, pose))
    with pytest.raises(ValueError):
        arm.ik(pose[:3])
    with pytest.raises(ValueError):
        arm.ik(pose[..., :3])
    with pytest.raises(ValueError):
        arm.fk(np.zeros(5))
    with pytest.raises(ValueError):
        arm.fk(np.full(6, np.nan))
    skewed = pose.copy()
    skewed[:3, :3] *= 1.01
    with pytest.raises(ValueError):
        arm.ik(skewed)
    sheared = pose.copy()
    sheared[0, 1] += 0.05
    with pytest.raises(ValueError):
        arm.ik(sheared)


def test_unreachable_pose_is_all_invalid_without_warnings(arm):
    pose = arm.fk(arm.home)
    pose[:3, 3] += 100.0
    solutions, valid = quiet_ik(arm, pose)
    assert not valid.any() and np.all(np.isnan(solutions))


def test_batches_match_single_poses(arm):
    q = sample(arm, 6, seed=5).reshape(2, 3, 6)
    pose = arm.fk(q)
    solutions, valid = arm.ik(pose)
    assert solutions.shape == (2, 3, 2, 6) and valid.shape == (2, 3, 2)
    for i in range(2):
        for j in range(3):
            # One pose is its batch row, bit for bit, as a batch of one or alone.
            one, one_valid = arm.ik(pose[i, j][None])
            np.testing.assert_array_equal(one[0], solutions[i, j])
            np.testing.assert_array_equal(one_valid[0], valid[i, j])
            single, single_valid = arm.ik(pose[i, j])
            np.testing.assert_array_equal(single, solutions[i, j])
            np.testing.assert_array_equal(single_valid, valid[i, j])
