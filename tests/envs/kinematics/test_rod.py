"""Rod mechanism of seed 004 (Balakin & Shamutdinov 2013): FK as the paper's eq. (1), the
general all-branch inverse, and the paper's q1 = q2 inverse (eq. 3) as a special case."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import least_squares

from ikbranch_gym.envs.kinematics.rod import RodMechanism, psi_from_sides

N_CONFIGS = 1000
FK_TOL = 1e-9
#: Two joint vectors name the same branch when they agree this closely (rad, modulo 2π).
SAME_Q = 1e-7
FULL = ((-np.pi, np.pi),) * 3


def angle_distance(q_a, q_b):
    """Largest per-joint distance modulo 2π (every joint is revolute)."""
    return np.abs(np.remainder(np.asarray(q_a) - q_b + np.pi, 2 * np.pi) - np.pi).max(axis=-1)


def paper_eq1(arm, q1, q2, q3):
    """Eq. (1) of the paper, written out with its own symbols."""
    lpp, b, a, psi, gamma = arm.lp_prime, arm.b, arm.a, arm.psi, arm.gamma
    bracket = -lpp * np.cos(q2 + psi - q1 - gamma) + b * np.cos(q1 + gamma) - a / 2
    return np.stack(
        [
            bracket * np.sin(q3),
            bracket * np.cos(q3),
            lpp * np.sin(q2 + psi - q1 - gamma) + b * np.sin(q1 + gamma),
        ],
        -1,
    )


def sample(arm, n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(n, arm.dof))


def translation(pose):
    return pose[..., :3, 3]


@pytest.fixture(params=["default", "full"])
def arm(request):
    """The paper-sized arm, and one whose joints turn fully so that all four branches occur."""
    return RodMechanism() if request.param == "default" else RodMechanism(joint_limits=FULL)


def test_contract_attributes():
    arm = RodMechanism()
    assert arm.name == "rod_mechanism" and arm.target == "position"
    assert arm.joint_names == ("q3", "q1", "q2") and arm.dof == 3
    assert arm.branch_labels == ("r+/elbow+", "r+/elbow-", "r-/elbow+", "r-/elbow-")
    assert arm.within_limits(arm.home)
    assert not arm.joint_limits.flags.writeable


def test_fk_is_eq1_and_the_table_frame_of_a_serial_chain():
    arm = RodMechanism()
    q = sample(RodMechanism(joint_limits=FULL), 200, seed=1)
    pose = arm.fk(q)
    q3, q1, q2 = q.T
    np.testing.assert_allclose(translation(pose), paper_eq1(arm, q1, q2, q3), atol=1e-12)
    # The same point and frame as a serial chain of elementary transforms (the recipe a
    # MuJoCo model follows): turntable about −Z, O1 at −a/2 on the turntable's y axis,
    # q1 about +x, O1O4 = b at γ, q2 about −x, O4P = l'p at ψ − γ from the horizontal.

    def rotation(axis, angle):
        c, s = np.cos(angle), np.sin(angle)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        out = np.zeros((len(angle), 4, 4))
        out[:, axis, axis] = out[:, 3, 3] = 1.0
        out[:, i, i] = out[:, j, j] = c
        out[:, i, j], out[:, j, i] = -s, s
        return out

    def shift(y, z):
        out = np.eye(4)
        out[1, 3], out[2, 3] = y, z
        return out

    gamma, table = arm.gamma, arm.psi - arm.gamma
    chain = (
        rotation(2, -q3)
        @ shift(-arm.a / 2, 0.0)
        @ rotation(0, q1)
        @ shift(arm.b * np.cos(gamma), arm.b * np.sin(gamma))
        @ rotation(0, -q2)
        @ shift(-arm.lp_prime * np.cos(table), arm.lp_prime * np.sin(table))
    )
    np.testing.assert_allclose(pose, chain, atol=1e-12)
    np.testing.assert_allclose(arm.fk(arm.home)[:3, :3], np.eye(3), atol=0)


def test_round_trip_on_random_configurations(arm):
    q = sample(arm, N_CONFIGS, seed=4004)
    target = arm.fk(q)
    solutions, valid = arm.ik(target)
    assert solutions.shape == (N_CONFIGS, 4, 3) and valid.shape == (N_CONFIGS, 4)
    assert np.all(np.isnan(solutions[~valid])) and np.all(np.isfinite(solutions[valid]))
    assert np.all(arm.within_limits(solutions[valid]))
    reached = translation(arm.fk(np.where(valid[..., None], solutions, 0.0)))
    error = np.abs(reached - translation(target)[:, None, :]).max(axis=-1)
    assert error[valid].max() < FK_TOL
    distance = np.where(valid, angle_distance(solutions, q[:, None, :]), np.inf)
    assert np.all(distance.min(axis=1) < SAME_Q), "the sampled q is not among the branches"


def test_branch_labels_mean_what_they_say():
    arm = RodMechanism(joint_limits=FULL)
    target = arm.fk(sample(arm, 500, seed=5))
    solutions, valid = arm.ik(target)
    _, q1, q2 = np.moveaxis(solutions, -1, 0)
    bracket = (
        -arm.lp_prime * np.cos(q2 + arm.psi - q1 - arm.gamma)
        + arm.b * np.cos(q1 + arm.gamma)
        - arm.a / 2
    )
    side = np.array([1, 1, -1, -1])
    elbow = np.array([1, -1, 1, -1])
    assert np.all((side * bracket)[valid] >= -FK_TOL)
    assert np.all((elbow * np.sin(q2 + arm.psi))[valid] >= -FK_TOL)
    assert valid.any(axis=0).all(), "with full ranges every branch occurs"


def numeric_solutions(arm, target, rng, starts):
    """Distinct converged least-squares solutions from random starts within the limits."""
    found = []
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    for _ in range(starts):
        result = least_squares(
            lambda q: translation(arm.fk(q)) - target,
            rng.uniform(lower, upper),
            bounds=(lower, upper),
            xtol=1e-14,
            ftol=1e-14,
            gtol=1e-14,
        )
        if np.max(np.abs(result.fun)) < 1e-10:
            found.append(result.x)
    return np.array(found).reshape(-1, 3)


def test_closed_form_is_complete_against_a_numerical_solver(arm):
    rng = np.random.default_rng(77)
    # Random reachable targets plus points near the axis, where both turntable sides exist.
    targets = list(translation(arm.fk(sample(arm, 5, seed=7))))
    targets += [np.array([0.01, -0.02, 0.55]), np.array([0.0, 0.03, 0.62])]
    n_found = 0
    for target in targets:
        pose = np.eye(4)
        pose[:3, 3] = target
        solutions, valid = arm.ik(pose)
        numeric = numeric_solutions(arm, target, rng, starts=10)
        n_found += len(numeric)
        for q in numeric:
            distance = angle_distance(solutions[valid], q)
            assert distance.size and distance.min() < 1e-6, f"missed {q} for {target}"
    assert n_found > 2 * len(targets), "the numerical solver should converge from most starts"


def test_the_papers_q1_equals_q2_inverse_is_one_of_the_branches():
    """Eq. (3) as derived from eq. (2): tan q3 = x/y (printed: sin q3 = tg(x/y)), taken with
    atan2 (the printed arctg(x/y) is only right for y > 0), and
    q1 = q2 = arcsin((z − l'p·sin(ψ − γ)) / b) − γ (right while q1 + γ ≤ 90°)."""
    arm = RodMechanism()
    rng = np.random.default_rng(3)
    q1 = rng.uniform(*arm.joint_limits[1], size=300)
    q3 = rng.uniform(*arm.joint_limits[0], size=300)
    x, y, z = translation(arm.fk(np.stack([q3, q1, q1], -1))).T
    # The bracket of eq. (2) must be positive for tan q3 = x/y to give q3 itself, not q3 ± π.
    bracket = -arm.lp_prime * np.cos(arm.psi - arm.gamma) + arm.b * np.cos(q1 + arm.gamma)
    bracket -= arm.a / 2
    q3_paper = np.where(bracket >= 0, np.arctan2(x, y), np.arctan2(-x, -y))
    q12_paper = np.arcsin((z - arm.lp_prime * np.sin(arm.psi - arm.gamma)) / arm.b) - arm.gamma
    paper = np.stack([q3_paper, q12_paper, q12_paper], -1)
    np.testing.assert_allclose(translation(arm.fk(paper)), np.stack([x, y, z], -1), atol=1e-12)
    pose = np.broadcast_to(np.eye(4), (300, 4, 4)).copy()
    pose[:, :3, 3] = np.stack([x, y, z], -1)
    solutions, valid = arm.ik(pose)
    distance = np.where(valid, angle_distance(solutions, paper[:, None, :]), np.inf)
    assert np.all(distance.min(axis=1) < SAME_Q)
    # The printed single-valued arctg(x/y) is off by π whenever |q3| > 90° ...
    behind = np.cos(q3) < 0
    assert behind.any()
    np.testing.assert_allclose(
        np.abs(np.remainder(np.arctan(x / y) - q3_paper + np.pi, 2 * np.pi) - np.pi)[behind],
        np.pi,
        atol=1e-9,
    )
    # ... and the arcsin principal value misses q1 + γ > 90° (reachable with wider ranges).
    wide = RodMechanism(joint_limits=FULL)
    q1_steep = np.pi / 2 - wide.gamma + 0.3
    x, y, z = translation(wide.fk(np.array([0.0, q1_steep, q1_steep])))
    arcsin = np.arcsin((z - wide.lp_prime * np.sin(wide.psi - wide.gamma)) / wide.b) - wide.gamma
    assert abs(arcsin - q1_steep) > 0.5


def test_corrected_law_of_cosines_gives_lp():
    """O1P = lp at q2 = 0 for every q1; the printed ψ = arccos(b / (2 l'p)) would not."""
    arm = RodMechanism()
    q1 = np.linspace(*arm.joint_limits[1], 7)
    q = np.stack([np.zeros_like(q1), q1, np.zeros_like(q1)], -1)
    p = translation(arm.fk(q))
    o1 = np.stack([np.zeros_like(q1), np.full_like(q1, -arm.a / 2), np.zeros_like(q1)], -1)
    np.testing.assert_allclose(np.linalg.norm(p - o1, axis=-1), arm.lp, atol=1e-12)
    assert psi_from_sides(arm.b, arm.lp, arm.lp_prime) == pytest.approx(arm.psi, abs=1e-12)
    printed = np.arccos((arm.b**2 + arm.lp_prime**2 - arm.lp_prime**2) / (2 * arm.b * arm.lp_prime))
    assert abs(printed - arm.psi) > 0.1


def test_batched_leading_axes_and_rotation_is_ignored():
    arm = RodMechanism()
    q = sample(arm, 10, seed=9).reshape(2, 5, 3)
    pose = arm.fk(q)
    assert pose.shape == (2, 5, 4, 4)
    solutions, valid = arm.ik(pose)
    assert solutions.shape == (2, 5, 4, 3) and valid.shape == (2, 5, 4)
    scrambled = pose.copy()
    scrambled[..., :3, :3] = 7.0  # position-only: not a rotation, and not read
    again, valid_again = arm.ik(scrambled)
    np.testing.assert_array_equal(valid_again, valid)
    np.testing.assert_array_equal(again[valid], solutions[valid])


@pytest.mark.parametrize(
    "bad",
    [
        np.full((4, 4), np.nan),
        np.eye(3),
        np.eye(4)[None, :3],
        np.array([[1.0, 0, 0, np.inf], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]),
    ],
)
def test_bad_targets_raise_value_error(bad):
    with pytest.raises(ValueError):
        RodMechanism().ik(bad)


@pytest.mark.parametrize("bad", [np.zeros(2), np.zeros((5, 4)), np.array([0.0, np.nan, 0.0])])
def test_bad_joint_vectors_raise_value_error(bad):
    with pytest.raises(ValueError):
        RodMechanism().fk(bad)


@pytest.mark.parametrize(
    "params",
    [{"b": 0.0}, {"lp_prime": -0.1}, {"a": -0.1}, {"psi": 0.0}, {"psi": 4.0}, {"b": np.nan}],
)
def test_impossible_dimensions_raise_value_error(params):
    with pytest.raises(ValueError):
        RodMechanism(**params)


def test_unreachable_targets_are_invalid_without_warnings():
    arm = RodMechanism(joint_limits=FULL)
    targets = np.broadcast_to(np.eye(4), (4, 4, 4)).copy()
    targets[0, :3, 3] = (5.0, 0.0, 0.0)  # beyond b + l'p from O1
    targets[1, :3, 3] = (0.0, 0.0, 0.1)  # within b − l'p of O1 on either side of the axis
    targets[2, :3, 3] = (0.0, 0.0, -3.0)
    targets[3, :3, 3] = (0.0, 0.0, 0.0)  # on the axis, where q3 is free, but too close to O1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solutions, valid = arm.ik(targets)
        default_solutions, default_valid = RodMechanism().ik(targets)
    assert not valid.any() and np.all(np.isnan(solutions))
    assert not default_valid.any() and np.all(np.isnan(default_solutions))


def test_target_on_the_axis_sets_the_free_turntable_angle():
    arm = RodMechanism(joint_limits=FULL)
    pose = np.eye(4)
    pose[2, 3] = 0.6
    solutions, valid = arm.ik(pose)
    assert valid.all()
    np.testing.assert_allclose(np.abs(solutions[:, 0]), [0, 0, np.pi, np.pi], atol=1e-12)
    reached = translation(arm.fk(solutions))
    np.testing.assert_allclose(reached, np.broadcast_to(pose[:3, 3], (4, 3)), atol=FK_TOL)
