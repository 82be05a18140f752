"""``task="file"``: the env plays a waypoint file (``envs/tasks/file_task.py``), refusing
rows no branch reaches with the row's line and the reason."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.paper_example import example_poses

PAPER_FILE = Path(__file__).parents[3] / "examples" / "paper_worked_example.csv"
HEADER = "name,x,y,z,qw,qx,qy,qz\n"


def _file(tmp_path, rows: list[str]) -> str:
    path = tmp_path / "job.csv"
    path.write_text(HEADER + "".join(row + "\n" for row in rows))
    return str(path)


def _env(path, **kwargs) -> IKBranchEnv:
    kwargs = {"arm": "anthropomorphic", "scene": "empty", **kwargs}
    return IKBranchEnv(task="file", task_file=path, **kwargs)


def test_the_paper_file_plays_the_paper_transfer():
    filed = _env(str(PAPER_FILE), scene="milling_cell")
    built_in = IKBranchEnv(arm="anthropomorphic", scene="milling_cell", task="paper_transfer")
    assert filed.n_waypoints == 2
    filed.reset(seed=0)
    built_in.reset(seed=0)
    np.testing.assert_array_equal(filed.task.poses, example_poses())
    assert filed.task.free_start and built_in.task.free_start
    # Same cell, same poses: every step prices the same.
    travel = 0.0
    for action in (0, 0):
        _, reward, _, _, info = filed.step(action)
        _, expected, _, _, _ = built_in.step(action)
        assert reward == expected
        travel += info["travel"]
    assert np.degrees(travel) == pytest.approx(275.1458, abs=1e-3)  # the paper's 275.15°
    with pytest.raises(ValueError, match="exactly 2 waypoints"):
        _env(str(PAPER_FILE), n_waypoints=3)


def test_a_given_start_is_the_episodes_start(tmp_path):
    path = _file(tmp_path, ["a,0.5,0.0,0.6,0,1,0,0", "b,0.5,0.2,0.6,0,1,0,0"])
    start = [0.1, 0.2, -0.3, 0.0, 0.4, 0.0]
    env = _env(path, task_start=start)
    env.reset(seed=0)
    assert not env.task.free_start
    np.testing.assert_array_equal(env.q, start)
    with pytest.raises(ValueError, match="6 finite joint values"):
        _env(path, task_start=[0.0] * 5)
    with pytest.raises(ValueError, match="outside the joint limits"):
        _env(path, task_start=[0.0, 0.0, 0.0, 0.0, 9.0, 0.0])


def test_unreachable_rows_are_named_with_their_line_and_reason(tmp_path):
    # Line 3 is 10 m away; line 4 stands on the x axis, where both shoulder branches turn
    # the base by ±90° (the arm's base angle counts from y), outside a base narrowed to
    # ±0.1 rad; line 2, on the y axis, keeps its base-angle-0 branches.
    path = _file(tmp_path, ["ok,0.0,0.5,0.6,0,1,0,0", "far,10,0,0.6,0,1,0,0",
                            "side,0.5,0.0,0.6,0,1,0,0"])
    limits = make_arm("anthropomorphic").joint_limits.copy()
    limits[0] = (-0.1, 0.1)
    with pytest.raises(ValueError) as error:
        _env(path, arm_params={"joint_limits": limits.tolist()})
    message = str(error.value)
    assert "2 of 3 waypoints" in message
    assert "line 3" in message and "out of reach" in message
    assert "line 4" in message and "outside the joint limits" in message
    assert "line 2" not in message


def test_a_position_only_arm_is_refused_before_the_rows_are_read(tmp_path):
    path = _file(tmp_path, ["far,10,0,0.6,0,1,0,0"])
    with pytest.raises(ValueError, match="position-only"):
        _env(path, arm="rod_mechanism")


def test_unknown_scene_options_are_a_value_error():
    with pytest.raises(ValueError, match="unknown scene_options"):
        IKBranchEnv(arm="kuka_kr6_r700", scene="milling_cell", task="tool_changes",
                    scene_options={"base_pos": [-1.0, 0.0, 0.0], "bsae_rpy": [0, 0, 0]})
    with pytest.raises(ValueError, match="task='file'"):
        IKBranchEnv(arm="anthropomorphic", task="file")
    with pytest.raises(ValueError, match="task_start"):
        IKBranchEnv(arm="anthropomorphic", task_start=[0.0] * 6)
