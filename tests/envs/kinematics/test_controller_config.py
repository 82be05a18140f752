"""KUKA Status/Turn and ABB confdata (envs/kinematics/controller_config.py): each
closed-form branch is exactly one configuration of the controller's (the IK's branches
and the controllers' bits describe the same three choices), the usual postures are S 2
and cfx 0, and the per-axis parts follow their definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.controller_config import abb_confdata, kuka_status_turn


def _branch_configurations(arm, configuration):
    rng = np.random.default_rng(4)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(400, 6))
    candidates, valid = arm.ik(arm.fk(q))
    found: dict[str, set[int]] = {}
    for m, b in zip(*np.nonzero(valid), strict=True):
        label = arm.closed_form_labels[arm.branch_closed_form[b]]
        found.setdefault(label, set()).add(configuration(candidates[m, b]))
    return found


def test_kuka_status_is_the_closed_form_branch():
    arm = make_arm("kuka_kr6_r700")
    found = _branch_configurations(arm, lambda q: int(kuka_status_turn(arm, q)[0]))
    assert len(found) == 8 and all(len(values) == 1 for values in found.values())
    status = {label: values.pop() for label, values in found.items()}
    assert len(set(status.values())) == 8  # eight branches, eight status values
    assert status["front/elbow-up/wrist+"] == 2  # the usual posture: 'B010'
    assert status["front/elbow-up/wrist-"] == 6  # the wrist flipped: bit 2
    assert status["back/elbow-up/wrist+"] & 1 and not status["front/elbow-down/wrist+"] & 1


@pytest.mark.parametrize("name", ["abb_irb2400", "abb_irb2600", "abb_irb4600"])
def test_abb_cfx_is_the_closed_form_branch(name):
    arm = make_arm(name)
    found = _branch_configurations(arm, lambda q: int(abb_confdata(arm, q)[3]))
    assert all(len(values) == 1 for values in found.values())
    cfx = {label: values.pop() for label, values in found.items()}
    assert len(set(cfx.values())) == len(cfx)
    assert cfx["front/elbow-up/wrist+"] == 0 and cfx["front/elbow-up/wrist-"] == 1


def test_per_axis_parts_follow_their_definitions():
    kuka, abb = make_arm("kuka_kr6_r700"), make_arm("abb_irb2400")
    q = np.radians([30.0, -60.0, 100.0, -20.0, 45.0, -30.0])
    _, turn = kuka_status_turn(kuka, q)
    assert int(turn) == 0b101010  # A2, A4, A6 negative
    assert int(kuka_status_turn(kuka, np.radians([0, -90, 90, 0, 90, 0]))[0]) == 2
    assert int(kuka_status_turn(kuka, np.radians([0, -90, 90, 0, 0, 0]))[0]) == 6  # A5 = 0
    rng = np.random.default_rng(5)
    for row in rng.uniform(abb.joint_limits[:, 0], abb.joint_limits[:, 1], size=(50, 6)):
        cf1, cf4, cf6, _ = abb_confdata(abb, row)
        for value, angle in ((cf1, row[0]), (cf4, row[3]), (cf6, row[5])):
            assert value * 90.0 <= math.degrees(angle) < (value + 1) * 90.0
    assert list(abb_confdata(abb, np.radians([0, 0, 0, 0, 30, 0]))) == [0, 0, 0, 0]
