"""The kinematics contract, checked for every registered arm."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import ARM_NAMES, INDUSTRIAL_ARM_NAMES, SEED_ARM_NAMES, make_arm
from ikbranch_gym.envs.kinematics.arm import PRISMATIC, REVOLUTE

N_CONFIGS = 1000
FK_TOL = 1e-9


def sample_configurations(arm, n, seed):
    rng = np.random.default_rng(seed)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    return rng.uniform(lower, upper, size=(n, arm.dof))


def joint_distance(arm, q_a, q_b):
    """Largest per-joint distance, revolute joints compared modulo 2π."""
    delta = np.abs(q_a - q_b)
    revolute = arm.revolute_mask
    delta[..., revolute] = np.abs(np.remainder(delta[..., revolute] + np.pi, 2 * np.pi) - np.pi)
    return delta.max(axis=-1)


def compared_part(arm, pose):
    """Position-only arms are judged on the translation, the others on the whole pose."""
    return pose[..., :3, 3] if arm.target == "position" else pose


@pytest.fixture(params=ARM_NAMES)
def arm(request):
    return make_arm(request.param)


#: The six-axis arms' branches as their docstrings list them: shoulder slowest, wrist fastest.
SIX_AXIS_BRANCHES = (
    "front/elbow-up/wrist+", "front/elbow-up/wrist-", "front/elbow-down/wrist+",
    "front/elbow-down/wrist-", "back/elbow-up/wrist+", "back/elbow-up/wrist-",
    "back/elbow-down/wrist+", "back/elbow-down/wrist-",
)
WRIST_BRANCHES = ("wrist+", "wrist-")
#: Every arm, in registry order, written out from the papers (docs/kinematics.md, the
#: seeds' joint tables) and the data sheets: joint types (R revolute, P prismatic), the
#: closed-form branches in solver order, what the target is, and whether fk is one arm
#: relative to another. The seed arms come first: ``SEED_ARM_NAMES`` is a slice.
ARMS = {
    "cartesian": ("PPPRRR", WRIST_BRANCHES, "pose", False),
    "cylindrical": ("PRPRRR", WRIST_BRANCHES, "pose", False),
    "spherical": ("RRPRRR", WRIST_BRANCHES, "pose", False),
    "anthropomorphic": ("RRRRRR", SIX_AXIS_BRANCHES, "pose", False),
    "cylindrical4": ("PRPR", ("unique",), "pose", False),
    "dual_rrp_rpp": ("RRPRPP", ("phi1+", "phi1-"), "pose", True),
    "dual_rrr_ppp": ("RRRPPP", ("phi2+", "phi2-"), "pose", True),
    "dual_ppr_prr": ("PPRPRR", ("phi5+", "phi5-"), "pose", True),
    "rod_mechanism": ("RRR", ("r+/elbow+", "r+/elbow-", "r-/elbow+", "r-/elbow-"),
                      "position", False),
    **{name: ("RRRRRR", SIX_AXIS_BRANCHES, "pose", False)
       for name in ("opw", "kuka_kr6_r700", "abb_irb2400", "abb_irb2600", "abb_irb4600",
                    "ur", "ur5e", "ur10e")},
}
N_SEED_ARMS = 9


def test_registry_lists_every_arm_in_order():
    assert ARM_NAMES == tuple(ARMS)
    assert SEED_ARM_NAMES == tuple(ARMS)[:N_SEED_ARMS]
    assert INDUSTRIAL_ARM_NAMES == tuple(ARMS)[N_SEED_ARMS:]


@pytest.mark.parametrize("name", ["cartesian", "cylindrical", "spherical"])
def test_wrist_branches_are_named_by_the_sign_of_the_wrist_bend(name):
    # Their only branches are the wrist's: R_w = Ry(a)·Rx(b)·Ry(c) (Klyuiko 1986, eq. 1),
    # b = ±arccos R_w[1,1] the bend between the arm axis and the tool axis, joint 4. The
    # other arms' labels are checked against their geometry in their own test files.
    arm = make_arm(name)
    solutions, valid = arm.ik(arm.fk(sample_configurations(arm, 500, seed=13)))
    bend = solutions[..., 4]
    for k, label in enumerate(arm.branch_labels):
        sign = 1.0 if label == "wrist+" else -1.0
        assert np.all(sign * bend[valid[:, k], k] > 0), label
    both = valid.all(axis=1)
    assert both.mean() > 0.5, "both wrist branches exist for most poses"
    np.testing.assert_allclose(bend[both, 0], -bend[both, 1], atol=1e-12)


def test_unknown_arm_and_bad_parameters_are_value_errors():
    with pytest.raises(ValueError, match="unknown arm"):
        make_arm("scara")
    with pytest.raises(ValueError, match="bad parameters"):
        make_arm("anthropomorphic", wingspan=3.0)
    with pytest.raises(ValueError, match="l2 must be positive"):
        make_arm("anthropomorphic", l2=-1.0)
    with pytest.raises(ValueError, match="lower < upper"):
        make_arm("cartesian", joint_limits=[[1, 0]] * 6)
    with pytest.raises(ValueError, match="home configuration lies outside"):
        make_arm("anthropomorphic", home=[0, 0, 0, 0, 3.0, 0])
    # Revolute limits beyond [-pi, pi] are turn windows now (test_turns.py), up to a bound.
    assert make_arm("anthropomorphic", joint_limits=[[-4, 4]] * 6).n_branches == 8 * 2**6
    with pytest.raises(ValueError, match=r"joint_limits allow .* branches"):
        make_arm("anthropomorphic", joint_limits=[[-40, 40]] * 6)


def test_contract_attributes(arm):
    joints, closed_form, target, relative = ARMS[arm.name]
    kinds = {"R": REVOLUTE, "P": PRISMATIC}
    assert arm.joint_types == tuple(kinds[kind] for kind in joints)
    assert arm.dof == len(joints) == len(arm.joint_names)
    assert arm.closed_form_labels == closed_form
    assert (arm.target, arm.relative) == (target, relative)
    assert arm.joint_limits.shape == (arm.dof, 2)
    assert arm.n_branches == len(arm.branch_labels) == len(set(arm.branch_labels))
    assert arm.home.shape == (arm.dof,)
    assert arm.within_limits(arm.home)
    assert not arm.joint_limits.flags.writeable, "parameters are frozen data"
    pose = arm.fk(arm.home)
    assert pose.shape == (4, 4) and np.all(np.isfinite(pose))


def test_round_trip_on_random_configurations(arm):
    q = sample_configurations(arm, N_CONFIGS, seed=20260)
    pose = arm.fk(q)
    solutions, valid = arm.ik(pose)
    assert solutions.shape == (N_CONFIGS, arm.n_branches, arm.dof)
    assert valid.shape == (N_CONFIGS, arm.n_branches)
    # Every valid branch reproduces the pose, every invalid row is NaN.
    assert np.all(np.isnan(solutions[~valid]))
    assert np.all(np.isfinite(solutions[valid]))
    reposed = arm.fk(np.where(valid[..., None], solutions, 0.0))
    error = np.abs(compared_part(arm, reposed) - compared_part(arm, pose)[:, None])
    assert error[valid].max() < FK_TOL
    # The configuration we started from is one of the valid branches.
    distance = joint_distance(arm, solutions, q[:, None, :])
    distance = np.where(valid, distance, np.inf)
    assert np.all(distance.min(axis=1) < 1e-7)
    # Valid branches are inside the limits.
    assert np.all(arm.within_limits(solutions[valid]))


def test_batch_shapes_broadcast(arm):
    q = sample_configurations(arm, 6, seed=3).reshape(2, 3, arm.dof)
    pose = arm.fk(q)
    assert pose.shape == (2, 3, 4, 4)
    solutions, valid = arm.ik(pose)
    assert solutions.shape == (2, 3, arm.n_branches, arm.dof)
    # One pose, as a batch of one or bare, is the batch's row, bit for bit (one driver;
    # test_compiled.py covers degenerate poses).
    one, one_valid = arm.ik(pose[1, 2][None])
    np.testing.assert_array_equal(one[0], solutions[1, 2])
    np.testing.assert_array_equal(one_valid[0], valid[1, 2])
    single, single_valid = arm.ik(pose[1, 2])
    np.testing.assert_array_equal(single_valid, valid[1, 2])
    np.testing.assert_array_equal(single, solutions[1, 2])


def test_ik_is_deterministic(arm):
    pose = arm.fk(sample_configurations(arm, 50, seed=5))
    first, second = arm.ik(pose), arm.ik(pose.copy())
    np.testing.assert_array_equal(first[0], second[0])
    np.testing.assert_array_equal(first[1], second[1])


def test_bad_input_is_a_value_error(arm):
    pose = arm.fk(arm.home)
    with pytest.raises(ValueError, match="NaN or inf"):
        arm.ik(np.where(np.eye(4, dtype=bool), np.nan, pose))
    with pytest.raises(ValueError, match="NaN or inf"):
        arm.fk(np.full(arm.dof, np.inf))
    with pytest.raises(ValueError, match="shape"):
        arm.ik(pose[:3])
    with pytest.raises(ValueError, match="shape"):
        arm.fk(np.zeros(arm.dof + 1))
    with pytest.raises(ValueError, match="numeric"):
        arm.fk(["a"] * arm.dof)
    if arm.target == "pose":
        skewed = pose.copy()
        skewed[:3, :3] *= 1.01
        with pytest.raises(ValueError, match="not orthonormal"):
            arm.ik(skewed)
        mirrored = pose.copy()
        mirrored[:3, 0] *= -1.0
        with pytest.raises(ValueError, match="reflection"):
            arm.ik(mirrored)


def test_unreachable_pose_is_all_invalid_without_warnings(arm):
    pose = arm.fk(arm.home)
    pose[:3, 3] += 100.0  # far beyond every arm's reach
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solutions, valid = arm.ik(pose)
    assert not valid.any()
    assert np.all(np.isnan(solutions))


def test_revolute_branches_are_wrapped_only_where_the_limits_lie_within_pi(arm):
    solutions, valid = arm.ik(arm.fk(sample_configurations(arm, 200, seed=9)))
    for joint, (lower, upper) in enumerate(arm.joint_limits):
        if arm.joint_types[joint] != REVOLUTE:
            continue
        values = solutions[..., joint][valid]
        if -np.pi <= lower and upper <= np.pi:
            # The seeds' convention: a half turn is reported as -pi.
            assert np.all(values >= -np.pi) and np.all(values < np.pi)
        else:
            # Wider limits: the values are where the limits put them, not wrapped.
            assert np.all((values >= lower - 1e-9) & (values <= upper + 1e-9))
            if upper - lower > 2 * np.pi:
                assert np.any(np.abs(values) > np.pi), "no branch uses the extra turn"


def test_positions_are_the_translation_of_fk_bit_for_bit(arm):
    # Clutter is drawn beside these points: an arm's own position formula (no rotation)
    # must give fk's bits, or every episode's clutter would move.
    rng = np.random.default_rng(3)
    limits = arm.joint_limits
    q = rng.uniform(limits[:, 0], limits[:, 1], size=(2, 5, arm.dof))
    np.testing.assert_array_equal(arm.positions(q), arm.fk(q)[..., :3, 3])
    np.testing.assert_array_equal(arm.positions(q[0, 0]), arm.fk(q[0, 0])[:3, 3])
    with pytest.raises(ValueError, match="q must have shape"):
        arm.positions(q[..., :-1])
