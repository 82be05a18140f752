"""The worked example's cell: the paper's recommended transfer is free, others are not."""

from __future__ import annotations

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import (
    RECOMMENDED_BRANCHES,
    CollisionChecker,
    build_model,
    milling_cell_poses,
)

#: The paper's table (degrees) for solutions 1.1 and 2.1.
PAPER_1_1 = (-22.43, 22.97, -85.88, 69.82, 80.0, 64.70)
PAPER_2_1 = (48.83, 4.16, -19.98, 0.0, 105.81, 41.17)


@pytest.fixture(scope="module")
def cell():
    arm = make_arm("anthropomorphic")
    checker = CollisionChecker(build_model("anthropomorphic", "milling_cell"), dof=arm.dof)
    (q1, ok1), (q2, ok2) = (arm.ik(pose) for pose in milling_cell_poses())
    assert ok1.all() and ok2.all()
    return arm, checker, q1, q2


def test_poses_are_the_papers_points():
    pose1, pose2 = milling_cell_poses()
    np.testing.assert_allclose(pose1[:3, 3], (0.525, 1.272, 0.800))
    np.testing.assert_allclose(pose2[:3, 3] + 0.35 * pose2[:3, 1], (-1.475, 1.290, 1.450))
    np.testing.assert_allclose(pose1[:3, 1], (1, 0, 0), atol=1e-12)  # tool along +X0
    np.testing.assert_allclose(pose2[:3, 1], (0, 0, 1), atol=1e-12)  # tool up, into the spindle


def test_recommended_branches_are_the_papers_1_1_and_2_1(cell):
    _, _, q1, q2 = cell
    i, j = RECOMMENDED_BRANCHES
    # The table is printed to 0.01°; its φ5 = 80.0 is rounded to 0.1°.
    np.testing.assert_allclose(np.degrees(q1[i]), PAPER_1_1, atol=0.03)
    np.testing.assert_allclose(np.degrees(q2[j]), PAPER_2_1, atol=0.03)


def test_recommended_transfer_is_free(cell):
    _, checker, q1, q2 = cell
    i, j = RECOMMENDED_BRANCHES
    assert not checker.collides(q1[i]) and not checker.collides(q2[j])
    result = checker.check_path(q1[i], q2[j])
    assert not result.collides, result.contacts


def test_other_branch_choices_collide(cell):
    arm, checker, q1, q2 = cell
    at_rack, at_spindle = checker.collides(q1), checker.collides(q2)
    assert 0 < at_rack.sum() < arm.n_branches
    assert 0 < at_spindle.sum() < arm.n_branches
    collides, first = checker.check_paths(q1[:, None], q2[None, :])
    assert collides.shape == (arm.n_branches, arm.n_branches)
    assert collides.sum() > collides.size // 2
    assert np.all(np.isnan(first) == ~collides)
    # A transfer that starts in a colliding pose collides at once; one that ends in one
    # collides somewhere.
    assert np.all(first[at_rack] == 0.0)
    assert collides[:, at_spindle].all()


def test_tool_is_on_by_default_and_optional():
    assert build_model("anthropomorphic", "milling_cell").body("tool").id > 0
    with pytest.raises(KeyError):
        build_model("anthropomorphic", "milling_cell", tool=False).body("tool")
