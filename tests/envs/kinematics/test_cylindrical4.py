"""The four-DOF cylindrical robot reaches only poses that satisfy the paper's constraints."""

from __future__ import annotations

import numpy as np

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.rotations import rot_x

ARM = make_arm("cylindrical4")


def test_constrained_poses_are_reachable_and_others_are_not():
    q = np.array([0.5, 0.4, 0.7, -1.2])
    pose = ARM.fk(q)
    solutions, valid = ARM.ik(pose)
    assert valid[0]
    np.testing.assert_allclose(solutions[0], q, atol=1e-12)
    # The paper's constraints hold for every reachable pose.
    n = pose[:3, :3]
    assert abs(n[2, 1]) < 1e-15  # z01 = z03: the tool axis y3 is horizontal
    np.testing.assert_allclose(-n[2, 0] / n[2, 2], n[1, 2] / n[1, 0])
    np.testing.assert_allclose(-pose[0, 3] / pose[1, 3], n[1, 0] / n[0, 0])
    np.testing.assert_allclose(-pose[0, 3] / pose[1, 3], -n[0, 1] / n[1, 1])
    # Tilting the tool axis out of the horizontal plane breaks them.
    tilted = pose.copy()
    tilted[:3, :3] = pose[:3, :3] @ rot_x(1e-6)
    solutions, valid = ARM.ik(tilted)
    assert not valid.any() and np.isnan(solutions).all()
