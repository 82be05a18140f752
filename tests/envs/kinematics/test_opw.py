"""The OPW family (Brandstötter et al. 2014, opw_kinematics' conventions) and its named arms."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.opw import OpwArm
from tests.envs.kinematics.industrial import (
    FK_TOL,
    assert_round_trip,
    chain,
    rot,
    sample,
    trans,
)

OPW_ARMS = ("opw", "kuka_kr6_r700", "abb_irb2400", "abb_irb2600", "abb_irb4600")
NAMED = OPW_ARMS[1:]
DEG = np.pi / 180.0


def theta_of(arm, q):
    """The paper's angles for joint values q, from the documented convention (not the
    package's helper): joint = (θ + offset)·sign, so θ = joint·sign − offset."""
    return np.asarray(q) * np.array(arm.sign_corrections) - np.array(arm.offsets)


def frames_of(arm, q):
    """Shoulder, elbow, wrist centre and flange frames of one configuration, from the
    product of elementary transforms Rz·T(a1, b, c1)·Ry·T(0, 0, c2)·Ry·T(a2, 0, c3)·
    Rz·Ry·Rz·T(0, 0, c4)."""
    t = theta_of(arm, q)
    base = rot("z", t[0])
    shoulder = base @ trans(arm.a1, arm.b, arm.c1)
    elbow = shoulder @ rot("y", t[1]) @ trans(0, 0, arm.c2)
    wrist = elbow @ rot("y", t[2]) @ trans(arm.a2, 0, arm.c3)
    flange = chain(wrist, rot("z", t[3]), rot("y", t[4]), rot("z", t[5]), trans(0, 0, arm.c4))
    return base, shoulder, elbow, wrist, flange


def random_opw(seed):
    """An OPW arm with random geometry (lateral offset b ≠ 0 included), offsets and signs."""
    rng = np.random.default_rng(seed)
    return OpwArm(
        a1=rng.uniform(-0.2, 0.3), a2=rng.uniform(-0.2, 0.2), b=rng.uniform(-0.15, 0.15),
        c1=rng.uniform(0.0, 0.8), c2=rng.uniform(0.3, 1.0), c3=rng.uniform(0.3, 1.0),
        c4=rng.uniform(0.0, 0.2), offsets=tuple(rng.uniform(-np.pi, np.pi, 6)),
        sign_corrections=tuple(rng.choice([-1, 1], 6)),
        joint_limits=[[-np.pi, np.pi]] * 6, home=[0.0] * 6,
    )


@pytest.fixture(params=OPW_ARMS)
def arm(request):
    return make_arm(request.param)


def full_circle(name):
    """The geometry of ``name`` with every joint limited to ±180° (no limit hides a
    branch or a singular configuration)."""
    return make_arm(name, joint_limits=[[-np.pi, np.pi]] * 6, home=[0.0, 0.0, 0.0, 0.0, 0.5, 0.0])


# ------------------------------------------------------------------------------ forward
@pytest.mark.parametrize(
    "arm",
    [*(make_arm(n) for n in OPW_ARMS), *(random_opw(s) for s in range(4))],
    ids=[*OPW_ARMS, *(f"random{s}" for s in range(4))],
)
def test_fk_is_the_product_of_elementary_transforms(arm):
    for q in sample(arm, 50, seed=3):
        np.testing.assert_allclose(arm.fk(q), frames_of(arm, q)[-1], rtol=0, atol=1e-13)


def _forward_term_for_term(arm, q):
    """opw_kinematics' forward() in numpy, one term at a time (each sine and cosine its
    own call, the matrices stacked): the formulation the published runs' waypoints and
    clutters were drawn with."""
    t = theta_of(arm, q)
    t1, t2, t3, t4, t5, t6 = (t[..., j] for j in range(6))
    psi3 = np.arctan2(arm.a2, arm.c3)
    k = np.sqrt(arm.a2 * arm.a2 + arm.c3 * arm.c3)
    cx1 = arm.c2 * np.sin(t2) + k * np.sin(t2 + t3 + psi3) + arm.a1
    cz1 = arm.c2 * np.cos(t2) + k * np.cos(t2 + t3 + psi3)
    s1, c1, s2, c2, s3, c3 = np.sin(t1), np.cos(t1), np.sin(t2), np.cos(t2), np.sin(t3), np.cos(t3)
    s4, c4, s5, c5, s6, c6 = np.sin(t4), np.cos(t4), np.sin(t5), np.cos(t5), np.sin(t6), np.cos(t6)
    zero = np.zeros_like(t1)
    r_0c = np.stack([
        np.stack([c1 * c2 * c3 - c1 * s2 * s3, -s1, c1 * c2 * s3 + c1 * s2 * c3], -1),
        np.stack([s1 * c2 * c3 - s1 * s2 * s3, c1, s1 * c2 * s3 + s1 * s2 * c3], -1),
        np.stack([-s2 * c3 - c2 * s3, zero, -s2 * s3 + c2 * c3], -1)], -2)
    r_ce = np.stack([
        np.stack([c4 * c5 * c6 - s4 * s6, -c4 * c5 * s6 - s4 * c6, c4 * s5], -1),
        np.stack([s4 * c5 * c6 + c4 * s6, -s4 * c5 * s6 + c4 * c6, s4 * s5], -1),
        np.stack([-s5 * c6, s5 * s6, c5], -1)], -2)
    rotation = r_0c @ r_ce
    centre = np.stack([cx1 * c1 - arm.b * s1, cx1 * s1 + arm.b * c1, cz1 + arm.c1], -1)
    pose = np.zeros((*t.shape[:-1], 4, 4))
    pose[..., :3, :3] = rotation
    pose[..., :3, 3] = centre + arm.c4 * rotation[..., :, 2]
    pose[..., 3, 3] = 1.0
    return pose


@pytest.mark.parametrize("shape", [(6,), (1, 6), (8, 6), (129, 6), (4, 3, 6)])
def test_fk_bits_are_forward_term_for_term(arm, shape):
    """FK equals opw_kinematics' forward() computed term by term, bit for bit, whatever
    the batch."""
    q = np.random.default_rng(7).uniform(-2 * np.pi, 2 * np.pi, size=shape)
    np.testing.assert_array_equal(arm.fk(q), _forward_term_for_term(arm, q))


def test_kr6_r700_flange_by_hand():
    arm = make_arm("kuka_kr6_r700")
    # q = 0: θ2 = 0·1 − (−90°) = 90°, so the arm lies horizontal along +x: reach
    # a1 + c2 + c3 + c4 = 0.025 + 0.315 + 0.365 + 0.080 = 0.785 m, height c1 − a2 = 0.435 m,
    # and the flange's z axis (the tool axis) points along +x.
    pose = arm.fk(np.zeros(6))
    np.testing.assert_allclose(pose[:3, 3], [0.785, 0.0, 0.435], atol=1e-15)
    np.testing.assert_allclose(pose[:3, :3], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-15)
    # KUKA's HOME (A2 −90°, A3 +90°): upper arm vertical (θ2 = 0), forearm horizontal
    # (θ3 = 90°): flange at x = a1 + c3 + c4 = 0.47 m, z = c1 + c2 − a2 = 0.75 m.
    pose = arm.fk(np.array([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]) * DEG)
    np.testing.assert_allclose(pose[:3, 3], [0.47, 0.0, 0.75], atol=1e-15)
    # A1 = +30° with sign correction −1 turns the arm by θ1 = −30° about z.
    pose = arm.fk(np.array([30.0, 0.0, 0.0, 0.0, 0.0, 0.0]) * DEG)
    np.testing.assert_allclose(
        pose[:3, 3], [0.785 * np.cos(-30 * DEG), 0.785 * np.sin(-30 * DEG), 0.435], atol=1e-15
    )
    # A6 with sign −1: +90° turns the flange by −90° about its own z axis.
    turned = arm.fk(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 90.0]) * DEG)
    expected = arm.fk(np.zeros(6))[:3, :3] @ rot("z", -np.pi / 2)[:3, :3]
    np.testing.assert_allclose(turned[:3, :3], expected, atol=1e-15)


def test_abb_irb2400_calibration_position_by_hand():
    arm = make_arm("abb_irb2400")
    # All axes 0: θ3 = 0 − (−90°) = 90°, upper arm vertical, forearm horizontal:
    # x = a1 + c3 + c4 = 0.94 m, z = c1 + c2 − a2 = 1.455 m, tool axis along +x.
    pose = arm.fk(np.zeros(6))
    np.testing.assert_allclose(pose[:3, 3], [0.94, 0.0, 1.455], atol=1e-15)
    np.testing.assert_allclose(pose[:3, 2], [1.0, 0.0, 0.0], atol=1e-15)


# ------------------------------------------------------------------------------ inverse
def test_round_trips_return_the_sampled_configuration_with_its_turns(arm):
    _solutions, valid = assert_round_trip(arm, sample(arm, 1000, seed=20260))
    assert valid.sum(axis=-1).min() >= 1


@pytest.mark.parametrize("seed", range(3))
def test_round_trips_for_random_geometry(seed):
    assert_round_trip(random_opw(seed), sample(random_opw(seed), 300, seed=seed))


# Completeness against a numerical multi-start solver: test_completeness.py.


def test_branch_labels_match_the_geometry(arm):
    q = sample(arm, 300, seed=11)
    solutions, valid = arm.ik(arm.fk(q))
    checked = 0
    # Turn windows do not change the geometry: one row per pose and closed-form branch.
    for closed, label in enumerate(arm.closed_form_labels):
        shoulder, elbow, wrist = label.split("/")
        family = arm.branch_closed_form == closed
        rows, ok = solutions[:, family], valid[:, family]
        for row in rows[ok.any(axis=1), np.argmax(ok, axis=1)[ok.any(axis=1)]]:
            base, s, e, w, _ = frames_of(arm, row)
            x_axis, z_axis = base[:3, 0], np.array([0.0, 0.0, 1.0])
            # front: the wrist centre is in front of the j1 axis in the j1 frame.
            reach = (w[:3, 3] - base[:3, 3]) @ x_axis
            if abs(reach) < 1e-9:
                continue
            assert (reach > 0) == (shoulder == "front"), (label, reach)
            # elbow-up: the elbow lies above the shoulder->wrist line, reach measured away
            # from the j1 axis (so the reach axis is -x for the back shoulder).
            h = np.sign(reach) * x_axis
            d, v = w[:3, 3] - s[:3, 3], e[:3, 3] - s[:3, 3]
            cross = (d @ h) * (v @ z_axis) - (d @ z_axis) * (v @ h)
            if abs(cross) > 1e-9:
                assert (cross > 0) == (elbow == "elbow-up"), (label, cross)
            sin5 = np.sin(theta_of(arm, row)[4])
            if abs(sin5) > 1e-9:
                assert (sin5 > 0) == (wrist == "wrist+"), (label, sin5)
            checked += 1
    assert checked > 500


@pytest.mark.parametrize("name", OPW_ARMS)
def test_every_closed_form_branch_occurs_within_full_circle_limits(name):
    arm = full_circle(name)
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
    _single, single_valid = arm.ik(pose)
    np.testing.assert_array_equal(single_valid, valid)
    return solutions, valid


@pytest.mark.parametrize("bend", [0.0, 1e-15, 1e-13, -1e-11, 1e-8, 1e-5])
@pytest.mark.parametrize("name", NAMED)
def test_straight_wrist_is_finite_and_exact(name, bend):
    arm = make_arm(name)
    for q in sample(arm, 20, seed=5):
        q[4] = (bend + arm.offsets[4]) * arm.sign_corrections[4]  # θ5 = bend
        solutions, valid = assert_finite_and_exact(arm, arm.fk(q))
        if bend != 0.0:
            continue
        # θ5 = 0: the free θ4 + θ6 is split evenly and both wrist branches of the sampled
        # posture are the same configuration.
        theta5 = theta_of(arm, solutions)[:, 4]
        straight = valid & (np.abs(np.sin(theta5)) < 1e-12)
        assert straight.any()
        for k in np.flatnonzero(straight):
            label = arm.branch_labels[k]
            flipped = label.replace("wrist+", "wrist?").replace("wrist-", "wrist+")
            twin = arm.branch_labels.index(flipped.replace("wrist?", "wrist-"))
            assert valid[twin]
            gap = np.abs(np.remainder(solutions[twin] - solutions[k] + np.pi, 2 * np.pi) - np.pi)
            assert gap.max() < 1e-12


def test_folded_wrist_is_finite_and_exact():
    arm = make_arm("opw")  # ±180° on j5 and offset5 = 0, sign5 = +1: θ5 = π is reachable
    for q in sample(arm, 20, seed=6):
        q[4] = np.pi
        assert_finite_and_exact(arm, arm.fk(q))


@pytest.mark.parametrize("name", OPW_ARMS)
def test_wrist_centre_on_the_j1_axis_is_finite_and_exact(name):
    arm = make_arm(name)
    k = np.hypot(arm.a2, arm.c3)
    psi3 = np.arctan2(arm.a2, arm.c3)
    rng = np.random.default_rng(8)
    hits = 0
    for _ in range(60):
        # Choose θ2, then θ3 so that a1 + c2 sin θ2 + k sin(θ2 + θ3 + ψ3) = 0.
        t2 = rng.uniform(-1.5, 1.0)
        ratio = -(arm.a1 + arm.c2 * np.sin(t2)) / k
        if abs(ratio) > 1:
            continue
        for angle in (np.arcsin(ratio), np.pi - np.arcsin(ratio)):
            t23 = angle - psi3
            theta = np.array([rng.uniform(-3, 3), t2, t23 - t2, *rng.uniform(-2, 2, 3)])
            q = (theta + np.array(arm.offsets)) * np.array(arm.sign_corrections)
            centre = frames_of(arm, q)[3][:3, 3]
            assert np.hypot(*centre[:2]) < 1e-12
            if not arm.within_limits(q):
                continue
            solutions, valid = assert_finite_and_exact(arm, arm.fk(q))
            hits += 1
            # θ1 is free: it is 0 (front) and π (back).
            cos1 = np.cos(theta_of(arm, solutions[valid])[:, 0])
            assert np.all(np.isclose(np.abs(cos1), 1.0, atol=1e-12))
    assert hits >= 3


@pytest.mark.parametrize("name", OPW_ARMS)
def test_stretched_elbow_keeps_both_elbow_branches(name):
    arm = full_circle(name)
    psi3 = np.arctan2(arm.a2, arm.c3)
    rng = np.random.default_rng(2)
    for _ in range(10):
        theta = rng.uniform(-1.0, 1.0, 6)
        theta[2] = -psi3  # β = θ3 + ψ3 = 0: upper arm and forearm aligned
        q = (theta + np.array(arm.offsets)) * np.array(arm.sign_corrections)
        q = np.remainder(q + np.pi, 2 * np.pi) - np.pi
        solutions, valid = assert_finite_and_exact(arm, arm.fk(q))
        # Both elbow branches of the sampled shoulder and wrist exist and coincide.
        gap = np.abs(np.remainder(solutions - q + np.pi, 2 * np.pi) - np.pi).max(axis=-1)
        own = int(np.nanargmin(np.where(valid, gap, np.nan)))
        assert gap[own] < 1e-6  # √ε conditioning of the elbow at the workspace boundary
        shoulder, elbow, wrist = arm.branch_labels[own].split("/")
        other = "elbow-down" if elbow == "elbow-up" else "elbow-up"
        twin = arm.branch_labels.index(f"{shoulder}/{other}/{wrist}")
        assert valid[twin] and np.abs(solutions[twin] - solutions[own]).max() < 1e-6


def test_lateral_offset_b_on_its_cylinder():
    arm = OpwArm(b=0.1, joint_limits=[[-np.pi, np.pi]] * 6, home=[0.0] * 6)
    # Wrist centre at distance |b| from the j1 axis: x = 0 in the j1 frame, both shoulder
    # branches coincide.
    k = np.hypot(arm.a2, arm.c3)
    psi3 = np.arctan2(arm.a2, arm.c3)
    t2 = 0.2
    t23 = np.arcsin(-(arm.a1 + arm.c2 * np.sin(t2)) / k) - psi3
    theta = np.array([0.7, t2, t23 - t2, 0.3, 0.8, -0.4])
    q = (theta + np.array(arm.offsets)) * np.array(arm.sign_corrections)
    assert_finite_and_exact(arm, arm.fk(q))
    # Inside the cylinder nothing is reachable.
    pose = arm.fk(q)
    centre = pose[:3, 3] - arm.c4 * pose[:3, 2]
    pose[:2, 3] -= 0.5 * centre[:2]
    assert not arm.ik(pose)[1].any() and not arm.ik(pose[None])[1].any()


# ------------------------------------------------------------------------- parameters
@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"c2": 0.0}, "c2 must be positive"),
        ({"c3": -0.3}, "c3 must be positive"),
        ({"c1": -0.1}, "c1 must be non-negative"),
        ({"c4": -0.01}, "c4 must be non-negative"),
        ({"a1": np.nan}, "a1 must be finite"),
        ({"offsets": (0.0,) * 5}, "offsets must have 6 entries"),
        ({"offsets": (0.0, np.nan, 0, 0, 0, 0)}, "offsets must be finite"),
        ({"offsets": "abcdef"}, "offsets must be six numbers"),
        ({"sign_corrections": (1,) * 7}, "sign_corrections must have 6 entries"),
        ({"sign_corrections": (1, 1, 0, 1, 1, 1)}, "sign_corrections must be \\+1 or -1"),
        ({"sign_corrections": (1, 1, 2, 1, 1, 1)}, "sign_corrections must be \\+1 or -1"),
        ({"joint_limits": [[0.0, 0.0]] + [[-1.0, 1.0]] * 5}, "lower < upper .*j1"),
        ({"joint_limits": [[-1.0, 1.0]] * 5 + [[np.nan, 1.0]]}, "joint_limits contains NaN"),
        ({"joint_limits": [[-1.0, 1.0]] * 5}, "joint_limits must have shape"),
    ],
)
@pytest.mark.parametrize("name", ["opw", "kuka_kr6_r700"])
def test_bad_parameters_are_value_errors_naming_the_parameter(name, params, message):
    with pytest.raises(ValueError, match=message):
        make_arm(name, **params)


def test_named_arms_carry_their_data_sheet_values():
    # The data sheets' values, degrees as printed there.
    kuka = make_arm("kuka_kr6_r700")
    np.testing.assert_allclose(np.rad2deg(kuka.joint_limits),
                               [[-170, 170], [-190, 45], [-120, 156], [-185, 185], [-120, 120],
                                [-350, 350]], atol=1e-12)
    assert (kuka.a1, kuka.a2, kuka.b, kuka.c1, kuka.c2, kuka.c3, kuka.c4) == (
        0.025, -0.035, 0.0, 0.400, 0.315, 0.365, 0.080)
    assert kuka.sign_corrections == (-1, 1, 1, -1, 1, -1)
    assert kuka.offsets == (0.0, -np.pi / 2, 0.0, 0.0, 0.0, 0.0)
    for name, geometry, limits in (
        ("abb_irb2400", (0.100, -0.135, 0, 0.615, 0.705, 0.755, 0.085),
         [[-180, 180], [-100, 110], [-60, 65], [-200, 200], [-120, 120], [-400, 400]]),
        ("abb_irb2600", (0.150, -0.115, 0, 0.445, 0.700, 0.795, 0.085),
         [[-180, 180], [-155, 95], [-155, 75], [-400, 400], [-120, 120], [-400, 400]]),
        ("abb_irb4600", (0.175, -0.175, 0, 0.495, 0.900, 0.960, 0.135),
         [[-180, 180], [-90, 150], [-180, 75], [-400, 400], [-125, 120], [-400, 400]]),
    ):
        abb = make_arm(name)
        assert (abb.a1, abb.a2, abb.b, abb.c1, abb.c2, abb.c3, abb.c4) == geometry
        assert abb.offsets == (0.0, 0.0, -np.pi / 2, 0.0, 0.0, 0.0)
        assert abb.sign_corrections == (1,) * 6
        np.testing.assert_allclose(np.rad2deg(abb.joint_limits), limits, atol=1e-12)


def test_a_user_enters_a_data_sheet():
    # Stäubli TX2-140-like values (a2 = 0, no offsets) with their own limits in degrees.
    arm = make_arm("opw", a1=0.150, a2=0.0, b=0.0, c1=0.550, c2=0.625, c3=0.625, c4=0.110,
                   offsets=(0,) * 6, sign_corrections=(1,) * 6,
                   joint_limits=np.deg2rad([[-180, 180], [-127.5, 127.5], [-152.5, 152.5],
                                            [-270, 270], [-121, 132.5], [-270, 270]]),
                   home=np.zeros(6))
    assert arm.n_branches == 8 * 2 * 2  # j4 and j6 span 540°: two turn windows each
    assert_round_trip(arm, sample(arm, 300, seed=4))


# ------------------------------------------------------------ the seed's arm in the family
def test_the_anthropomorphic_arm_is_an_opw_arm_with_a_rotated_tool_frame():
    """Klyuiko's arm is the OPW arm a1 = a2 = b = c4 = 0, c1 = l1, c2 = l2, c3 = l3 with
    offsets (−90°, −90°, 0, 0, 0, 0) and signs (1, −1, −1, 1, −1, 1), its gripper frame the
    flange frame turned by the constant F (x -> −y, y -> z, z -> −x, F = Ry(−90°)·Rz(−90°));
    its branch front/elbow-E/wrist± is the OPW branch front/elbow-E/wrist∓."""
    seed = make_arm("anthropomorphic")
    arm = make_arm("opw", a1=0.0, a2=0.0, b=0.0, c1=seed.l1, c2=seed.l2, c3=seed.l3, c4=0.0,
                   offsets=(-np.pi / 2, -np.pi / 2, 0, 0, 0, 0),
                   sign_corrections=(1, -1, -1, 1, -1, 1),
                   joint_limits=seed.joint_limits, home=seed.home)
    f = (rot("y", -np.pi / 2) @ rot("z", -np.pi / 2))[:3, :3]
    np.testing.assert_allclose(f, [[0, 0, -1], [-1, 0, 0], [0, 1, 0]], atol=1e-15)
    q = sample(seed, 500, seed=9)
    pose = arm.fk(q)
    pose[:, :3, :3] = pose[:, :3, :3] @ f
    np.testing.assert_allclose(pose, seed.fk(q), rtol=0, atol=1e-12)
    # The same eight configurations, the wrist sign swapped in the labels.
    seed_q, seed_ok = seed.ik(seed.fk(q))
    opw_q, opw_ok = arm.ik(arm.fk(q))
    for k, label in enumerate(seed.branch_labels):
        shoulder, elbow, wrist = label.split("/")
        twin = arm.branch_labels.index(
            f"{shoulder}/{elbow}/{'wrist-' if wrist == 'wrist+' else 'wrist+'}")
        both = seed_ok[:, k] & opw_ok[:, twin]
        assert both.sum() > 0.9 * max(seed_ok[:, k].sum(), 1)
        gap = np.abs(np.remainder(seed_q[both, k] - opw_q[both, twin] + np.pi, 2 * np.pi) - np.pi)
        assert gap.max() < 1e-9
