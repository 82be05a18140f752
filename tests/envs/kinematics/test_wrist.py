"""The shared Y-X-Y spherical wrist solver, at and near its singularities."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ikbranch_gym.envs.kinematics.wrist import solve_yxy_wrist, wrist_rotation

angles = st.floats(-np.pi, np.pi, exclude_max=True)


@settings(max_examples=300, deadline=None)
@given(
    a=angles,
    b=st.one_of(angles, st.floats(-1e-7, 1e-7), st.floats(np.pi - 1e-7, np.pi)),
    c=angles,
)
def test_both_branches_reproduce_the_rotation(a, b, c):
    rotation = wrist_rotation(np.float64(a), np.float64(b), np.float64(c))
    solutions = solve_yxy_wrist(rotation)
    assert solutions.shape == (2, 3) and np.all(np.isfinite(solutions))
    for row in solutions:
        assert np.abs(wrist_rotation(*row) - rotation).max() < 2e-12
    assert solutions[0, 1] >= 0.0 >= solutions[1, 1]


@pytest.mark.parametrize("theta", [-3.0, -0.7, 0.0, 0.5, 2.9])
def test_straight_wrist_splits_the_free_angle_evenly(theta):
    # b = 0: only a + c is defined.
    rotation = wrist_rotation(np.float64(theta), np.float64(0.0), np.float64(0.0))
    solutions = solve_yxy_wrist(rotation)
    np.testing.assert_array_equal(solutions[0], solutions[1])  # the branches coincide
    a, b, c = solutions[0]
    assert b == 0.0
    assert a == pytest.approx(theta / 2, abs=1e-12) and c == pytest.approx(theta / 2, abs=1e-12)


@pytest.mark.parametrize("theta", [-2.0, 0.0, 1.0])
def test_folded_wrist_splits_the_free_angle_evenly(theta):
    # b = pi: only a - c is defined.
    rotation = wrist_rotation(np.float64(theta), np.float64(np.pi), np.float64(0.0))
    solutions = solve_yxy_wrist(rotation)
    np.testing.assert_array_equal(solutions[0, [0, 2]], solutions[1, [0, 2]])
    assert solutions[0, 1] == np.pi and solutions[1, 1] == -np.pi  # the same joint angle
    a, b, c = solutions[0]
    assert a == pytest.approx(theta / 2, abs=1e-12) and c == pytest.approx(-theta / 2, abs=1e-12)
    assert np.abs(wrist_rotation(a, b, c) - rotation).max() < 1e-12
