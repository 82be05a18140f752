"""Universal Robots arms: UR's DH chain, Hawkins' 8 branches, the singular cases."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.ur import dh_transform
from tests.envs.kinematics.industrial import (
    FK_TOL,
    assert_round_trip,
    rot,
    sample,
    trans,
)

UR_ARMS = ("ur", "ur5e", "ur10e")
ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)


def dh_frames(arm, q):
    """Frames 0…6 of UR's DH chain, Rz(θ)·Tz(d)·Tx(a)·Rx(α) per joint, with α in floating
    point (the package uses exact cosines; the difference is 6e-17)."""
    d = (arm.d1, 0.0, 0.0, arm.d4, arm.d5, arm.d6)
    a = (0.0, arm.a2, arm.a3, 0.0, 0.0, 0.0)
    frames = [np.eye(4)]
    for joint in range(6):
        step = rot("z", q[joint]) @ trans(0, 0, d[joint]) @ trans(a[joint], 0, 0)
        frames.append(frames[-1] @ step @ rot("x", ALPHA[joint]))
    return frames


def full_circle(name):
    home = [0.0, -1.5, 1.5, -1.5, -1.5, 0.0]
    return make_arm(name, joint_limits=[[-np.pi, np.pi]] * 6, home=home)


@pytest.fixture(params=UR_ARMS)
def arm(request):
    return make_arm(request.param)


def test_fk_is_the_dh_chain(arm):
    for q in sample(arm, 50, seed=3):
        np.testing.assert_allclose(arm.fk(q), dh_frames(arm, q)[-1], rtol=0, atol=1e-13)
        np.testing.assert_allclose(arm.frames(q), np.stack(dh_frames(arm, q)), atol=1e-13)


@pytest.mark.parametrize("shape", [(6,), (1, 6), (8, 6), (129, 6), (4, 3, 6)])
def test_fk_bits_are_the_product_of_dh_transforms(arm, shape):
    """FK is dh_transform's six matrices multiplied in joint order, bit for bit, whatever
    the batch: the waypoints and clutters of published runs were drawn with these bits."""
    rng = np.random.default_rng(7)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, size=shape)
    d = (arm.d1, 0.0, 0.0, arm.d4, arm.d5, arm.d6)
    a = (0.0, arm.a2, arm.a3, 0.0, 0.0, 0.0)
    cos_alpha, sin_alpha = (0.0, 1.0, 1.0, 0.0, 0.0, 1.0), (1.0, 0.0, 0.0, 1.0, -1.0, 0.0)
    pose = dh_transform(q[..., 0], d[0], a[0], cos_alpha[0], sin_alpha[0])
    for joint in range(1, 6):
        pose = pose @ dh_transform(q[..., joint], d[joint], a[joint], cos_alpha[joint],
                                   sin_alpha[joint])
    np.testing.assert_array_equal(arm.fk(q), pose)


def test_ur5e_tool0_by_hand():
    arm = make_arm("ur5e")
    # q = 0: the arm stretched along x (a2 + a3 = −0.8172 m), the wrist offsets d4 + d6
    # towards −y, the tool flange d5 below the shoulder height d1; tool z along −y.
    pose = arm.fk(np.zeros(6))
    np.testing.assert_allclose(pose[:3, 3], [-0.8172, -0.2329, 0.0628], atol=1e-15)
    np.testing.assert_allclose(pose[:3, :3], [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-15)
    # The "ready" home pose (0, −90°, 90°, −90°, −90°, 0), frame by frame: upper arm up
    # (frame 2 at height d1 − a2), forearm along −x (frame 3 at x = a3), d4 along −y to
    # frame 4, whose z axis is −x: d5 along −x to frame 5, whose z axis is −z: d6 down.
    pose = arm.fk(arm.home)
    expected = [arm.a3 - arm.d5, -arm.d4, arm.d1 - arm.a2 - arm.d6]
    np.testing.assert_allclose(pose[:3, 3], expected, atol=1e-15)
    np.testing.assert_allclose(pose[:3, 2], [0, 0, -1], atol=1e-15)


def test_round_trips_return_the_sampled_configuration_with_its_turns(arm):
    assert_round_trip(arm, sample(arm, 1000, seed=20260))


# Completeness against a numerical multi-start solver: test_completeness.py.


def test_branch_labels_match_the_geometry(arm):
    q = sample(arm, 300, seed=11)
    solutions, valid = arm.ik(arm.fk(q))
    sign_a2 = np.sign(arm.a2)
    checked = 0
    # Turn windows do not change the geometry: one row per pose and closed-form branch.
    for closed, label in enumerate(arm.closed_form_labels):
        shoulder, elbow, wrist = label.split("/")
        family = arm.branch_closed_form == closed
        rows, ok = solutions[:, family], valid[:, family]
        for row in rows[ok.any(axis=1), np.argmax(ok, axis=1)[ok.any(axis=1)]]:
            frames = dh_frames(arm, row)
            x1 = frames[1][:3, 0]
            p5 = frames[5][:3, 3]
            reach = p5 @ x1
            if abs(reach) < 1e-9:
                continue
            # front: the wrist point on the side the upper arm points to at θ2 = 0.
            assert (sign_a2 * reach > 0) == (shoulder == "front"), (label, reach)
            # elbow-up: elbow above the shoulder -> forearm-end line, reach towards p5.
            h, z = np.sign(reach) * x1, np.array([0.0, 0.0, 1.0])
            s, e, w = (frames[i][:3, 3] for i in (1, 2, 3))
            d, v = w - s, e - s
            cross = (d @ h) * (v @ z) - (d @ z) * (v @ h)
            if abs(cross) > 1e-9:
                assert (cross > 0) == (elbow == "elbow-up"), (label, cross)
            if abs(np.sin(row[4])) > 1e-9:
                assert (np.sin(row[4]) > 0) == (wrist == "wrist+"), (label, row[4])
            checked += 1
    assert checked > 500


def test_every_closed_form_branch_occurs():
    arm = full_circle("ur5e")
    _solutions, valid = arm.ik(arm.fk(sample(arm, 500, seed=12)))
    assert valid.any(axis=0).all()


# ----------------------------------------------------------------------------- singular
def assert_finite_and_exact(arm, pose):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solutions, valid = arm.ik(pose[None])
    solutions, valid = solutions[0], valid[0]
    assert valid.any()
    assert np.all(np.isfinite(solutions[valid])) and np.all(np.isnan(solutions[~valid]))
    assert np.abs(arm.fk(solutions[valid]) - pose).max() < FK_TOL
    single, single_valid = arm.ik(pose)
    np.testing.assert_array_equal(single_valid, valid)
    assert np.abs(arm.fk(single[single_valid]) - pose).max() < FK_TOL
    return solutions, valid


@pytest.mark.parametrize("theta5", [0.0, np.pi, -np.pi, 1e-15, 1e-13, -1e-11, 1e-8, np.pi - 1e-12])
@pytest.mark.parametrize("name", UR_ARMS)
def test_wrist_singularity_is_finite_and_exact(name, theta5):
    arm = make_arm(name)
    for q in sample(arm, 20, seed=5):
        q[4] = theta5
        solutions, valid = assert_finite_and_exact(arm, arm.fk(q))
        if np.sin(theta5) == 0.0:
            # θ6 is free; both wrist rows of a singular posture are the same configuration.
            straight = valid & (np.abs(np.sin(solutions[:, 4])) < 1e-12)
            assert straight.any()
            for k in np.flatnonzero(straight):
                label = arm.branch_labels[k]
                other = label.replace("wrist+", "w?").replace("wrist-", "wrist+")
                twin = arm.branch_labels.index(other.replace("w?", "wrist-"))
                gap = np.remainder(solutions[twin] - solutions[k] + np.pi, 2 * np.pi) - np.pi
                assert valid[twin] and np.abs(gap).max() < 1e-12


@pytest.mark.parametrize("name", UR_ARMS)
def test_a_reachable_wrist_singular_pose_always_has_solutions(name):
    """Near the workspace boundary a fixed θ6 (ur_kinematics' default 0) can put frame 4
    out of the elbow's reach although other θ6 reach it: the free θ6 is chosen for reach."""
    arm = make_arm(name)
    rng = np.random.default_rng(9)
    stretched = 0
    for _ in range(60):
        q = np.array([rng.uniform(-3, 3), rng.uniform(-3, 0), rng.uniform(-0.3, 0.3),
                      rng.uniform(-3, 3), 0.0, rng.uniform(-3, 3)])
        if not arm.within_limits(q):
            continue
        _solutions, _valid = assert_finite_and_exact(arm, arm.fk(q))
        stretched += abs(q[2]) < 0.3
    assert stretched > 20


@pytest.mark.parametrize("name", UR_ARMS)
def test_shoulder_singularity_is_finite_and_exact(name):
    """Wrist point with no reach in the arm plane (p5 on the cylinder ρ = d4): upper arm
    straight up, forearm straight on (θ2 = −90°, θ3 = 0) and θ4 = ±90°. Both shoulder
    branches coincide there."""
    arm = make_arm(name)
    rng = np.random.default_rng(4)
    for theta4 in (np.pi / 2, -np.pi / 2):
        for _ in range(5):
            q = np.array([rng.uniform(-3, 3), -np.pi / 2, 0.0, theta4, *rng.uniform(-2, 2, 2)])
            p5 = dh_frames(arm, q)[5][:3, 3]
            assert abs(np.hypot(p5[0], p5[1]) - arm.d4) < 1e-12
            _solutions, valid = assert_finite_and_exact(arm, arm.fk(q))
            front = np.array([label.startswith("front") for label in arm.branch_labels])
            assert (valid & front).any() and (valid & ~front).any()
    # A hair inside the cylinder nothing is reachable.
    pose = arm.fk(np.array([0.3, -np.pi / 2, 0.0, np.pi / 2, 0.7, 0.2]))
    p5 = pose[:3, 3] - arm.d6 * pose[:3, 2]
    pose[:2, 3] -= 1e-6 * p5[:2] / np.hypot(*p5[:2])
    assert not arm.ik(pose)[1].any() and not arm.ik(pose[None])[1].any()


@pytest.mark.parametrize("name", UR_ARMS)
def test_stretched_elbow_keeps_both_elbow_branches(name):
    arm = full_circle(name)
    rng = np.random.default_rng(6)
    for _ in range(10):
        q = np.array([*rng.uniform(-2, 2, 2), 0.0, *rng.uniform(-2, 2, 3)])
        solutions, valid = assert_finite_and_exact(arm, arm.fk(q))
        gap = np.abs(solutions - q).max(axis=-1)
        own = int(np.nanargmin(np.where(valid, gap, np.nan)))
        assert gap[own] < 1e-6  # √ε conditioning of the elbow at the workspace boundary
        shoulder, elbow, wrist = arm.branch_labels[own].split("/")
        other = "elbow-down" if elbow == "elbow-up" else "elbow-up"
        twin = arm.branch_labels.index(f"{shoulder}/{other}/{wrist}")
        assert valid[twin] and np.abs(solutions[twin] - solutions[own]).max() < 1e-6


def test_both_singularities_at_once():
    arm = make_arm("ur5e")
    q = np.array([0.4, -np.pi / 2, 0.0, np.pi / 2, 0.0, 0.3])
    assert_finite_and_exact(arm, arm.fk(q))


# ------------------------------------------------------------------------- parameters
@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"d1": 0.0}, "d1 must be positive"),
        ({"d4": -0.1}, "d4 must be positive"),
        ({"d5": 0.0}, "d5 must be positive"),
        ({"d6": -1.0}, "d6 must be positive"),
        ({"a2": 0.0}, "a2 must be non-zero"),
        ({"a3": 0.0}, "a3 must be non-zero"),
        ({"a3": np.inf}, "a3 must be finite"),
        ({"joint_limits": [[1.0, -1.0]] * 6}, "lower < upper"),
    ],
)
@pytest.mark.parametrize("name", ["ur", "ur5e"])
def test_bad_parameters_are_value_errors_naming_the_parameter(name, params, message):
    with pytest.raises(ValueError, match=message):
        make_arm(name, **params)


def test_named_arms_carry_urs_values():
    ur5e, ur10e = make_arm("ur5e"), make_arm("ur10e")
    assert (ur5e.d1, ur5e.a2, ur5e.a3, ur5e.d4, ur5e.d5, ur5e.d6) == (
        0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996)
    assert (ur10e.d1, ur10e.a2, ur10e.a3, ur10e.d4, ur10e.d5, ur10e.d6) == (
        0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655)
    for arm in (ur5e, ur10e):
        np.testing.assert_allclose(np.rad2deg(arm.joint_limits),
                                   [[-360, 360]] * 2 + [[-180, 180]] + [[-360, 360]] * 3,
                                   atol=1e-12)


def test_positive_dh_lengths_work_too():
    # A UR-like arm described with positive a2, a3 (the elbow and shoulder labels follow
    # the geometry, not the sign convention).
    arm = make_arm("ur", a2=0.425, a3=0.3922)
    assert_round_trip(arm, sample(arm, 300, seed=2))
