"""Turn branches: every closed-form branch × every 2π shift the joint limits allow.

Expected counts and windows are worked out by hand from the data sheets' degrees (a
joint spanning S degrees has ⌈S / 360⌉ windows), never read back from the code.
"""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import INDUSTRIAL_ARM_NAMES, SEED_ARM_NAMES, make_arm
from ikbranch_gym.envs.kinematics.arm import MAX_BRANCHES
from tests.envs.kinematics.industrial import assert_round_trip, sample

#: name -> (K, {joint: windows as (lower, upper) in degrees}) by hand from the data sheets.
EXPECTED = {
    "opw": (8, {}),
    "ur": (8, {}),
    # A4 ±185° (370°: 2), A6 ±350° (700°: 2); A2 −190°/+45° spans 235°: 1 window.
    "kuka_kr6_r700": (32, {3: [(-185, 175), (175, 185)], 5: [(-350, 10), (10, 350)]}),
    # Axis 4 ±200° (400°: 2), axis 6 ±400° (800°: 3).
    "abb_irb2400": (48, {3: [(-200, 160), (160, 200)],
                         5: [(-400, -40), (-40, 320), (320, 400)]}),
    # Axes 4 and 6 ±400° (3 each).
    "abb_irb2600": (72, {3: [(-400, -40), (-40, 320), (320, 400)],
                         5: [(-400, -40), (-40, 320), (320, 400)]}),
    "abb_irb4600": (72, {3: [(-400, -40), (-40, 320), (320, 400)],
                         5: [(-400, -40), (-40, 320), (320, 400)]}),
    # ±360° (720°: 2) on all joints but the elbow (±180°): 8 × 2⁵ = 256.
    "ur5e": (256, {j: [(-360, 0), (0, 360)] for j in (0, 1, 3, 4, 5)}),
    "ur10e": (256, {j: [(-360, 0), (0, 360)] for j in (0, 1, 3, 4, 5)}),
}
LABEL_WINDOW = re.compile(r"^(?P<joint>\w+)@(?P<lo>-?[\d.]+)\.\.(?P<hi>-?[\d.]+)$")


@pytest.mark.parametrize("name", INDUSTRIAL_ARM_NAMES)
def test_branch_count_and_windows_follow_the_limits(name):
    arm = make_arm(name)
    k, windows = EXPECTED[name]
    assert arm.n_branches == k == len(arm.branch_labels) == len(set(arm.branch_labels))
    assert arm.n_closed_form == 8
    got = {joint: [tuple(np.rad2deg(w)) for w in ws] for joint, ws in arm.turn_windows}
    assert got.keys() == windows.keys()
    for joint, expected in windows.items():
        np.testing.assert_allclose(got[joint], expected, atol=1e-9)


@pytest.mark.parametrize("name", SEED_ARM_NAMES)
def test_seed_arms_have_no_turns(name):
    arm = make_arm(name)
    assert arm.turn_windows == ()
    assert arm.branch_labels == arm.closed_form_labels and arm.n_branches == arm.n_closed_form


@pytest.mark.parametrize("name", INDUSTRIAL_ARM_NAMES)
def test_labels_name_the_closed_form_branch_and_the_window_of_each_value(name):
    arm = make_arm(name)
    solutions, valid = arm.ik(arm.fk(sample(arm, 200, seed=31)))
    for k, label in enumerate(arm.branch_labels):
        parts = label.split("/")
        assert "/".join(parts[:3]) == arm.closed_form_labels[arm.branch_closed_form[k]]
        windows = parts[3:]
        assert len(windows) == len(arm.turn_windows)
        for (joint, _), window, slot in zip(arm.turn_windows, windows, arm.branch_turns[k],
                                            strict=True):
            match = LABEL_WINDOW.match(window)
            assert match and match["joint"] == arm.joint_names[joint]
            lo, hi = np.deg2rad(float(match["lo"])), np.deg2rad(float(match["hi"]))
            values = solutions[valid[:, k], k, joint]
            # Window edges are half-open [lo, hi) (the last one closed), LIMIT_TOL below.
            assert np.all(values >= lo - 1e-9) and np.all(values <= hi + 1e-9), label
            assert np.isclose(lo, arm.turn_windows[[j for j, _ in arm.turn_windows].index(joint)]
                              [1][slot][0])


@pytest.mark.parametrize("name", INDUSTRIAL_ARM_NAMES)
def test_every_shift_inside_the_limits_is_returned_and_no_other(name):
    """For sampled q: each q + 2π·n (n per turned joint) inside the limits is a valid
    branch, exactly; the closed-form family of q has no other valid branch."""
    arm = make_arm(name)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    turned = [joint for joint, _ in arm.turn_windows]
    q = sample(arm, 300, seed=32)
    solutions, valid = arm.ik(arm.fk(q))
    for row, rows, ok in zip(q, solutions, valid, strict=True):
        # The limits are a box: the allowed shifts are a product of per-joint choices.
        choices = [
            [row[j] + 2 * np.pi * n for n in range(-3, 4)
             if lower[j] - 1e-9 <= row[j] + 2 * np.pi * n <= upper[j] + 1e-9]
            for j in turned
        ]
        shifts = []
        for values in itertools.product(*choices):
            shifted = row.copy()
            shifted[turned] = values
            shifts.append(shifted)
        gap = np.abs(rows[None] - np.array(shifts)[:, None]).max(axis=-1)  # (shifts, K)
        gap = np.where(ok[None], gap, np.inf)
        assert np.all(gap.min(axis=1) < 1e-9)
        family = arm.branch_closed_form == arm.branch_closed_form[np.argmin(gap[0])]
        assert (ok & family).sum() == len(shifts)


@pytest.mark.parametrize("name", ["kuka_kr6_r700", "abb_irb2600", "ur5e"])
def test_turned_joints_differ_by_whole_turns_and_the_others_not_at_all(name):
    arm = make_arm(name)
    solutions, valid = arm.ik(arm.fk(sample(arm, 100, seed=33)))
    turned = np.zeros(arm.dof, dtype=bool)
    turned[[joint for joint, _ in arm.turn_windows]] = True
    for closed in range(arm.n_closed_form):
        rows = solutions[:, arm.branch_closed_form == closed]
        ok = valid[:, arm.branch_closed_form == closed]
        first = np.argmax(ok, axis=1)
        reference = rows[np.arange(len(rows)), first]
        delta = (rows - reference[:, None])[ok]
        turns = delta[:, turned] / (2 * np.pi)
        np.testing.assert_allclose(turns, np.round(turns), atol=1e-12)
        np.testing.assert_array_equal(delta[:, ~turned], 0.0)


def test_travel_counts_the_real_rotation():
    """KUKA A6 at +340°: the pose offers A6 = 340° and −20°, 360° apart; from A6 = 300°
    the nearer is 40° away, the other 320° (no wrap-around into ±180°)."""
    arm = make_arm("kuka_kr6_r700")
    q = arm.home.copy()
    q[5] = np.deg2rad(340.0)
    solutions, valid = arm.ik(arm.fk(q))
    same_posture = np.all(np.abs(solutions[:, :5] - q[:5]) < 1e-9, axis=-1) & valid
    a6 = np.sort(np.rad2deg(solutions[same_posture, 5]))
    np.testing.assert_allclose(a6, [-20.0, 340.0], atol=1e-9)
    start = np.deg2rad(300.0)
    np.testing.assert_allclose(np.sort(np.rad2deg(np.abs(np.deg2rad(a6) - start))), [40, 320])


def test_values_on_a_limit_stay_in_their_window():
    arm = make_arm("kuka_kr6_r700")
    for value in arm.joint_limits[5]:  # A6 = −350° and +350° exactly
        q = arm.home.copy()
        q[5] = value
        assert_round_trip(arm, q[None])


def test_a_span_of_whole_turns_keeps_the_lowest_representatives():
    """UR's ±360°: a value on a limit (−360°) has three representatives in the limits
    (−360°, 0°, 360°) but the arm enumerates two windows, [−360°, 0°) and [0°, 360°]; the
    top one (+360°, the other hard stop) is not returned (docs/kinematics_opw_ur.md)."""
    arm = make_arm("ur5e")
    q = arm.home.copy()
    q[0] = -2 * np.pi
    solutions, valid = arm.ik(arm.fk(q))
    posture = np.all(np.abs(solutions[:, 1:] - q[1:]) < 1e-9, axis=-1) & valid
    np.testing.assert_allclose(np.sort(solutions[posture, 0]), [-2 * np.pi, 0.0], atol=1e-9)


def test_wide_limits_on_a_seed_arm_enumerate_turns():
    limits = np.array(make_arm("anthropomorphic").joint_limits)
    limits[5] = np.deg2rad([-540.0, 540.0])  # φ6: 1080° -> 3 windows
    arm = make_arm("anthropomorphic", joint_limits=limits)
    assert arm.n_branches == 8 * 3
    assert arm.branch_labels[:3] == (
        "front/elbow-up/wrist+/phi6@-540..-180",
        "front/elbow-up/wrist+/phi6@-180..180",
        "front/elbow-up/wrist+/phi6@180..540",
    )
    assert_round_trip(arm, sample(arm, 500, seed=34))


def test_limits_beyond_pi_with_a_span_under_a_turn_shift_without_windows():
    # KUKA A2: −190°/+45° (outside ±180°, span 235°): one window, values where the limits are.
    arm = make_arm("kuka_kr6_r700")
    q = sample(arm, 500, seed=35)
    q[:, 1] = np.deg2rad(np.linspace(-190, 45, 500))
    solutions, valid = assert_round_trip(arm, q)
    assert np.any(solutions[..., 1][valid] < -np.pi)


def test_too_many_turn_windows_are_refused():
    limits = np.deg2rad([[-180, 180], [-180, 180], [-180, 180]] + [[-3600, 3600]] * 3)
    with pytest.raises(ValueError, match=f"at most {MAX_BRANCHES}"):
        make_arm("opw", joint_limits=limits)


def test_one_pose_and_a_batch_enumerate_the_same_turns():
    arm = make_arm("ur10e")
    poses = arm.fk(sample(arm, 30, seed=36))
    batched, batched_ok = arm.ik(poses)
    for pose, expected, expected_ok in zip(poses, batched, batched_ok, strict=True):
        single, single_ok = arm.ik(pose)
        np.testing.assert_array_equal(single_ok, expected_ok)
        np.testing.assert_array_equal(single, expected)
