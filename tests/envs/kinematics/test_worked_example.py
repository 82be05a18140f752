"""Klyuiko (1986)'s worked example, read straight off the anthropomorphic arm's IK."""

from __future__ import annotations

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.paper_example import (
    PRINTED_MIN_TRAVEL_DEG,
    PRINTED_TABLE_DEG,
    ROW_BRANCH,
    TABLE_MISPRINTS_DEG,
    corrected_table_deg,
    example_poses,
)

TABLE_TOL_DEG = 0.02


def angle_gap_deg(a, b):
    return np.abs(np.remainder(np.asarray(a) - np.asarray(b) + 180.0, 360.0) - 180.0)


@pytest.fixture(scope="module")
def solved():
    arm = make_arm("anthropomorphic")
    solutions, valid = arm.ik(example_poses())
    return arm, np.degrees(solutions), valid


def test_eight_valid_branches_per_position(solved):
    _, degrees, valid = solved
    assert valid.shape == (2, 8) and valid.all()
    # Eight genuinely different configurations at each position.
    for position in range(2):
        rows = degrees[position]
        gaps = angle_gap_deg(rows[:, None, :], rows[None, :, :]).max(axis=-1)
        assert np.all(gaps[~np.eye(8, dtype=bool)] > 1.0)


@pytest.mark.parametrize("row", sorted(PRINTED_TABLE_DEG))
def test_table_rows_are_among_the_branches(solved, row):
    _, degrees, _ = solved
    position, index = row.split(".")
    expected = corrected_table_deg()[row]
    computed = degrees[int(position) - 1, ROW_BRANCH[index]]
    assert angle_gap_deg(computed, expected).max() < TABLE_TOL_DEG
    # And the printed row is matched by no other branch better than by its own.
    gaps = angle_gap_deg(degrees[int(position) - 1], expected).max(axis=-1)
    assert gaps.argmin() == ROW_BRANCH[index]


@pytest.mark.parametrize(("row", "joint"), sorted(TABLE_MISPRINTS_DEG))
def test_misprints_are_refuted_by_forward_kinematics(solved, row, joint):
    arm, _, _ = solved
    target = example_poses()[int(row[0]) - 1]
    printed = np.radians(PRINTED_TABLE_DEG[row])
    corrected = np.radians(corrected_table_deg()[row])
    printed_error = np.abs(arm.fk(printed) - target).max()
    corrected_error = np.abs(arm.fk(corrected) - target).max()
    assert corrected_error < 1e-3  # table precision: 0.01° on metre-long links
    assert printed_error > 0.1


def test_minimum_travel_is_the_papers(solved):
    _, degrees, _ = solved
    travel = np.abs(degrees[0, :4, None, :] - degrees[1, None, :4, :]).sum(axis=-1)
    assert travel.min() == pytest.approx(PRINTED_MIN_TRAVEL_DEG, abs=0.005)
    best = {tuple(pair) for pair in np.argwhere(np.isclose(travel, travel.min(), atol=1e-9))}
    assert best == {(0, 0), (1, 1)}  # 1.1 -> 2.1 and 1.2 -> 2.2


def test_worked_example_cli_prints_the_table(capsys):
    from ikbranch_gym.envs import worked_example

    worked_example.main()
    out = capsys.readouterr().out
    assert "Minimum 275.15° (1.1 -> 2.1, 1.2 -> 2.2)" in out
    assert out.count("front/elbow-up/wrist+") == 2
