"""TransitionCost: the travel and time of a move, priced identically however it is batched."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ikbranch_gym.envs.costs import DEFAULT_PRISMATIC_SPEED, DEFAULT_REVOLUTE_SPEED, TransitionCost
from ikbranch_gym.envs.kinematics import make_arm


def test_travel_is_the_papers_sum_of_joint_moves():
    cost = TransitionCost.for_arm(make_arm("anthropomorphic"))
    q0 = np.zeros(6)
    q1 = np.radians([10.0, -20.0, 30.0, 0.0, 5.0, -5.0])
    assert cost.travel(q0, q1) == pytest.approx(np.radians(70.0))
    assert cost.time(q0, q1) == pytest.approx(np.radians(30.0) / DEFAULT_REVOLUTE_SPEED)


def test_prismatic_joints_are_scaled_and_have_their_own_speed():
    arm = make_arm("cartesian")
    assert not arm.revolute_mask[:3].any()  # x, y, z slides
    cost = TransitionCost.for_arm(arm, prismatic_scale=2.0, time_weight=1.0)
    q1 = np.zeros(arm.dof)
    q1[0] = 0.5
    assert cost.travel(np.zeros(arm.dof), q1) == pytest.approx(1.0)
    assert cost.time(np.zeros(arm.dof), q1) == pytest.approx(0.5 / DEFAULT_PRISMATIC_SPEED)


def test_joint_weights_and_speeds_override_the_defaults():
    arm = make_arm("anthropomorphic")
    cost = TransitionCost.for_arm(arm, joint_weights=[2, 0, 0, 0, 0, 1],
                                  joint_speeds=[1, 1, 1, 1, 1, 0.25])
    q1 = np.array([0.1, 5.0, 5.0, 5.0, 5.0, 0.2])
    assert cost.travel(np.zeros(6), q1) == pytest.approx(0.4)
    assert cost.time(np.zeros(6), q1) == pytest.approx(5.0)


@pytest.mark.parametrize(
    "kwargs",
    [{"travel_weight": -1}, {"time_weight": np.nan}, {"prismatic_scale": -0.5},
     {"joint_weights": [1, 1]}, {"joint_weights": [1, 1, 1, 1, 1, np.inf]},
     {"joint_speeds": [1, 1, 1, 1, 1, 0]}, {"joint_speeds": [1] * 7}],
)
def test_bad_parameters_raise(kwargs):
    with pytest.raises(ValueError):
        TransitionCost.for_arm(make_arm("anthropomorphic"), **kwargs)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(1, 9))
def test_a_move_costs_the_same_to_the_bit_alone_or_batched(seed, k):
    # step() prices one move, edge_rewards() and planners a batch: they must agree exactly.
    rng = np.random.default_rng(seed)
    cost = TransitionCost.for_arm(make_arm("spherical"), joint_weights=rng.uniform(0, 2, 6))
    q0, q1 = rng.uniform(-3, 3, 6), rng.uniform(-3, 3, (k, 6))
    batched, times = cost.travel(q0[None], q1), cost.time(q0[None], q1)
    grid = cost.travel(q1[:, None, :], q1[None, :, :])
    for j in range(k):
        assert cost.travel(q0, q1[j]) == batched[j] == cost.travel(q0[None], q1[j : j + 1])[0]
        assert cost.time(q0, q1[j]) == times[j]
        assert cost.travel(q1[j], q1[0]) == grid[j, 0]


def test_travel_is_symmetric_and_zero_for_no_move():
    cost = TransitionCost.for_arm(make_arm("cylindrical4"))
    rng = np.random.default_rng(1)
    a, b = rng.uniform(-1, 1, (2, 4))
    assert cost.travel(a, b) == cost.travel(b, a) and cost.travel(a, a) == 0.0


@pytest.mark.parametrize(("name", "degrees_per_second"), [
    # Typed from the data sheets (and the ROS-Industrial / UR descriptions that carry them).
    ("kuka_kr6_r700", (360, 300, 360, 381, 388, 615)),
    ("abb_irb2400", (150, 150, 150, 360, 360, 450)),
    ("abb_irb2600", (175, 175, 175, 360, 360, 500)),
    ("abb_irb4600", (175, 175, 175, 250, 250, 360)),
    ("ur5e", (180, 180, 180, 180, 180, 180)),
    ("ur10e", (120, 120, 180, 180, 180, 180)),
])
def test_rated_speeds_are_the_data_sheets(name, degrees_per_second):
    cost = TransitionCost.for_arm(make_arm(name), joint_speeds="rated")
    np.testing.assert_allclose(np.degrees(cost.speeds), degrees_per_second, rtol=1e-12)
    q1 = np.zeros(6)
    q1[5] = np.radians(90.0)  # the last joint alone: its own speed sets the time
    assert cost.time(np.zeros(6), q1) == pytest.approx(90.0 / degrees_per_second[5])


def test_rated_speeds_follow_the_arm_inside_a_free_tool_axis():
    from ikbranch_gym.envs.tool_axis import ToolAxisArm

    arm = ToolAxisArm(make_arm("kuka_kr6_r700"), None, np.radians([-30.0, 0.0, 30.0]))
    cost = TransitionCost.for_arm(arm, joint_speeds="rated")
    np.testing.assert_allclose(np.degrees(cost.speeds), (360, 300, 360, 381, 388, 615))


@pytest.mark.parametrize(("arm", "speeds", "message"), [
    ("anthropomorphic", "rated", "anthropomorphic has no data-sheet speeds"),
    ("kuka_kr6_r700", "fast", 'a list of speeds or "rated"'),
])
def test_rated_speeds_refuse_what_has_no_data_sheet(arm, speeds, message):
    with pytest.raises(ValueError, match=message):
        TransitionCost.for_arm(make_arm(arm), joint_speeds=speeds)
