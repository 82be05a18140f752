"""Controller programs of ``ikbranch plan`` (train/plan/controllers.py): each file parsed
by a grammar of the language's forms it uses (KRL ``DEF``/``DEFDAT`` with ``E6AXIS`` and
``PTP``; RAPID ``MODULE`` with ``jointtarget`` and ``MoveAbsJ``; URScript ``def`` with
``movej``), and its targets read back equal to the plan's joint values."""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.controller_config import abb_confdata, kuka_status_turn
from ikbranch_gym.envs.kinematics.rotations import quaternion_matrix, rot_x, rot_y, rot_z
from ikbranch_gym.envs.tasks.waypoint_file import write_waypoints
from ikbranch_gym.envs.tools import Tool
from ikbranch_gym.train import plan as plan_module
from ikbranch_gym.train.plan import EXIT_INPUT, EXIT_OK, main
from ikbranch_gym.train.plan.controllers import krl, rapid, refused_lines, urscript
from tests.train.test_plan import EXAMPLES, rows_of

NUMBER = r"-?\d+(?:\.\d+)?(?:E\d+)?"
NAME = r"[A-Za-z][A-Za-z0-9_]{0,23}"
COMMENT = r"[\x20-\x7e]*"  # printable ASCII
INTEGER = r"\d+"


def _numbers(count: int, separator: str = ",") -> str:
    return separator.join([rf"({NUMBER})"] * count)


KRL_FRAME = ",".join(rf"{key} ({NUMBER})" for key in "XYZABC")
KRL_EXTERNALS = ",".join(rf"E{j} {NUMBER}" for j in range(1, 7))
KRL_SRC = {
    "def": re.compile(rf"DEF ({NAME})\( \)"),
    "comment": re.compile(rf"  ;{COMMENT}"),
    "base": re.compile(r"  \$BASE=\$NULLFRAME"),
    "tool": re.compile(r"  \$TOOL=TCP_PLAN"),
    "move": re.compile(rf"  (PTP|LIN) ({NAME})(?: ;{COMMENT})?"),
    "end": re.compile(r"END"),
}
KRL_DAT = {
    "defdat": re.compile(rf"DEFDAT ({NAME}) PUBLIC"),
    "frame": re.compile(rf"  DECL FRAME TCP_PLAN=\{{{KRL_FRAME}\}}"),
    "e6axis": re.compile(rf"  DECL E6AXIS ({NAME})=\{{"
                         + ",".join(rf"A{j} ({NUMBER})" for j in range(1, 7)) + ","
                         + KRL_EXTERNALS + r"\}"),
    "e6pos": re.compile(rf"  DECL E6POS ({NAME})=\{{{KRL_FRAME},S ({INTEGER}),T ({INTEGER}),"
                        + KRL_EXTERNALS + r"\}"),
    "enddat": re.compile(r"ENDDAT"),
}
RAPID_POSE = rf"\[{_numbers(3)}\],\[{_numbers(4)}\]"
RAPID = {
    "module": re.compile(rf"MODULE ({NAME})"),
    "comment": re.compile(rf"  !{COMMENT}"),
    "tool": re.compile(rf"  PERS tooldata tPlan:=\[TRUE,\[{RAPID_POSE}\],"
                       r"\[0\.001,\[0,0,0\.001\],\[1,0,0,0\],0,0,0\]\];"),
    "jointtarget": re.compile(rf"  CONST jointtarget ({NAME}):=\[\[{_numbers(6)}\],"
                              r"\[(?:9E9,){5}9E9\]\];"),
    "robtarget": re.compile(rf"  CONST robtarget ({NAME}):=\[{RAPID_POSE},"
                            rf"\[(-?{INTEGER}),(-?{INTEGER}),(-?{INTEGER}),({INTEGER})\],"
                            r"\[(?:9E9,){5}9E9\]\];"),
    "proc": re.compile(r"  PROC main\(\)"),
    "conf": re.compile(r"    Conf[JL] \\On;"),
    "move": re.compile(rf"    (MoveAbsJ|MoveJ|MoveL) ({NAME}),v100,fine,tPlan;(?: !{COMMENT})?"),
    "endproc": re.compile(r"  ENDPROC"),
    "endmodule": re.compile(r"ENDMODULE"),
}
UR_POSE = rf"p\[{_numbers(6, ', ')}\]"
UR_JOINTS = rf"\[{_numbers(6, ', ')}\]"
UR_COMMENT = rf"(?:  #{COMMENT})?"
URSCRIPT = {
    "def": re.compile(rf"def ({NAME})\(\):"),
    "comment": re.compile(rf"  #{COMMENT}"),
    "tcp": re.compile(rf"  set_tcp\({UR_POSE}\)"),
    "movej": re.compile(rf"  movej\({UR_JOINTS}, a=1\.4, v=1\.05\){UR_COMMENT}"),
    "movej_pose": re.compile(rf"  movej\(get_inverse_kin\({UR_POSE}, qnear={UR_JOINTS}\), "
                             rf"a=1\.4, v=1\.05\){UR_COMMENT}"),
    "movel": re.compile(rf"  movel\({UR_POSE}, a=1\.2, v=0\.25\){UR_COMMENT}"),
    "end": re.compile(r"end"),
}
KRL_SRC_ORDER = ["def", "comment", "base", "tool", "move", "end"]
KRL_DAT_ORDER = ["defdat", "frame", ("e6axis", "e6pos"), "enddat"]
RAPID_ORDER = ["module", "comment", "tool", ("jointtarget", "robtarget"), "proc", "conf",
               "move", "endproc", "endmodule"]
URSCRIPT_ORDER = ["def", "comment", "tcp", ("movej", "movej_pose", "movel"), "end"]


def _parse(text: str, grammar: dict[str, re.Pattern], order: list,
           newline: str = "\n") -> list[tuple[str, tuple[str, ...]]]:
    """Each line matched by exactly one rule, the rules in the sequence ``order`` allows:
    the first once, each later entry (a rule, or a tuple of rules that may interleave)
    repeated or left out, the last once."""
    assert text.endswith(newline) and text.isascii()
    lines = text[: -len(newline)].split(newline)
    assert all("\r" not in line and "\n" not in line for line in lines)
    parsed = []
    for line in lines:
        matches = [rule for rule, pattern in grammar.items() if pattern.fullmatch(line)]
        assert len(matches) == 1, (line, matches)
        parsed.append((matches[0], grammar[matches[0]].fullmatch(line).groups()))
    slots = [entry if isinstance(entry, tuple) else (entry,) for entry in order]
    position = 0
    for rule, _ in parsed:  # the rules appear in the allowed order (repeats allowed)
        while rule not in slots[position]:
            position += 1
            assert position < len(slots), [rule for rule, _ in parsed]
    assert parsed[0][0] in slots[0] and parsed[-1][0] in slots[-1]
    return parsed


def _joint_rows(csv_path: Path, arm: str = "kuka_kr6_r700") -> np.ndarray:
    names = make_arm(arm).joint_names
    return np.array([[float(row[name]) for name in names] for row in rows_of(csv_path)])


@pytest.fixture
def cell(tmp_path, monkeypatch):
    shutil.copytree(EXAMPLES, tmp_path / "examples", ignore=shutil.ignore_patterns("*.coacd"))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_krl_program_of_the_deburring_passes(cell):
    assert main(["--arm", "kuka_kr6_r700", "--waypoints", "examples/deburring_passes.csv",
                 "--out", "plan.csv", "--krl", "deburr.src"]) == EXIT_OK
    src = (cell / "deburr.src").read_bytes().decode("ascii")
    dat = (cell / "deburr.dat").read_bytes().decode("ascii")
    moves = _parse(src, KRL_SRC, KRL_SRC_ORDER, newline="\r\n")
    decls = _parse(dat, KRL_DAT, KRL_DAT_ORDER, newline="\r\n")
    assert moves[0][1] == ("deburr",) and decls[0][1] == ("deburr",)
    targets = {groups[0]: np.radians([float(v) for v in groups[1:]])
               for rule, groups in decls if rule == "e6axis"}
    assert {groups[0] for rule, groups in moves if rule == "move"} == {"PTP"}
    order = [groups[1] for rule, groups in moves if rule == "move"]
    assert len(targets) == len(order) == 62 and set(order) == set(targets)
    planned = _joint_rows(cell / "plan.csv")
    np.testing.assert_allclose(np.array([targets[name] for name in order]), planned,
                               rtol=0, atol=math.radians(1e-9))


def test_rapid_module_of_the_welding_seam(cell):
    assert main(["--arm", "abb_irb2400", "--waypoints", "examples/welding_seam.csv",
                 "--scene", "examples/welding_cell.xml", "--tool",
                 "examples/welding_torch.json", "--out", "weld.csv",
                 "--rapid", "weld_seam.mod"]) == EXIT_OK
    text = (cell / "weld_seam.mod").read_text(encoding="ascii")
    parsed = _parse(text, RAPID, RAPID_ORDER)
    assert parsed[0][1] == ("weld_seam",)
    targets = {groups[0]: np.radians([float(v) for v in groups[1:]])
               for rule, groups in parsed if rule == "jointtarget"}
    assert {groups[0] for rule, groups in parsed if rule == "move"} == {"MoveAbsJ"}
    order = [groups[1] for rule, groups in parsed if rule == "move"]
    assert len(order) == 9 and set(order) == set(targets)
    np.testing.assert_allclose(np.array([targets[name] for name in order]),
                               _joint_rows(cell / "weld.csv"), rtol=0,
                               atol=math.radians(1e-9))
    # The torch's j6 turns beyond −180° on this seam: written as the branch has it, and the
    # CSV names the turn (a revolution back) beside the configuration.
    assert min(targets[name][5] for name in order) < -math.pi
    for row, name in zip(rows_of(cell / "weld.csv"), order, strict=True):
        j6 = targets[name][5]
        assert row["turns"].split()[-1] == ("j6:-1" if j6 < -math.pi else "j6:0")
        assert row["turns"].startswith("j1:0 j2:0 j3:0 ")


def test_urscript_program_of_a_ur5e_job(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    generated = IKBranchEnv(arm="ur5e", scene="empty", task="random", n_waypoints=5)
    generated.reset(seed=4)
    path = write_waypoints(tmp_path / "job.csv", generated.task.poses, names=[
        "pick", "über", "place", "a\nb", "home"])
    assert main(["--arm", "ur5e", "--waypoints", str(path), "--out", "plan.csv",
                 "--max-joint-step", "off", "--urscript", "ur_job.script"]) == EXIT_OK
    text = (tmp_path / "ur_job.script").read_text(encoding="ascii")
    parsed = _parse(text, URSCRIPT, URSCRIPT_ORDER)
    joints = np.array([[float(v) for v in groups] for rule, groups in parsed
                       if rule == "movej"])
    np.testing.assert_allclose(joints, _joint_rows(tmp_path / "plan.csv", "ur5e"), rtol=0,
                               atol=1e-9)
    assert "# waypoint 1: ?ber" in text  # comments are ASCII


@pytest.mark.parametrize(("args", "message"), [
    (["--arm", "abb_irb2400", "--krl", "job.src"],
     "--krl: a KUKA program needs a KUKA arm, not abb_irb2400"),
    (["--arm", "kuka_kr6_r700", "--rapid", "job.mod"],
     "--rapid: an ABB program needs an ABB arm, not kuka_kr6_r700"),
    (["--arm", "kuka_kr6_r700", "--urscript", "job.script"],
     "--urscript: a Universal Robots program needs a Universal Robots arm"),
    (["--arm", "kuka_kr6_r700", "--krl", "1job.src"],
     "--krl: the file name '1job' must be a controller name"),
    (["--arm", "kuka_kr6_r700", "--krl", "deburring-job.src"], "must be a controller name"),
    (["--arm", "kuka_kr6_r700", "--krl", "a_program_name_of_thirty_chars.src"],
     "at most 24"),
    (["--arm", "kuka_kr6_r700", "--krl", "job.krl"], "--krl job.krl: the file name must end "
                                                     "in .src"),
])
def test_bad_program_outputs_are_refused(cell, capsys, args, message):
    assert main(["--waypoints", "examples/deburring_passes.csv", "--out", "plan.csv",
                 *args]) == EXIT_INPUT
    assert message in capsys.readouterr().err
    assert not (cell / "plan.csv").exists()


def _planned(args: list[str]):
    """The Plan of an ``ikbranch plan`` command line (dp_oracle only)."""
    request = plan_module.request_from_args(plan_module.parser().parse_args(args))
    return plan_module.plan(request)


def _kuka_pose(groups: tuple[str, ...]) -> np.ndarray:
    x, y, z, a, b, c = (float(v) for v in groups)
    pose = np.eye(4)
    pose[:3, :3] = rot_z(math.radians(a)) @ rot_y(math.radians(b)) @ rot_x(math.radians(c))
    pose[:3, 3] = np.array([x, y, z]) / 1000.0
    return pose


def _only_solution(arm, pose: np.ndarray, configuration, config_of) -> np.ndarray:
    """The one IK row of ``pose`` whose controller configuration is ``configuration``
    (joint values read to 1e-9 rad, as a controller reads them: −1e-17 is 0, not negative)."""
    rows, ok = arm.ik(pose)
    matching = [rows[k] for k in np.flatnonzero(ok)
                if [int(v) for v in np.ravel(config_of(arm, np.round(rows[k], 9) + 0.0))]
                == [int(v) for v in configuration]]
    assert len(matching) == 1, (configuration, len(matching))
    return matching[0]


def test_krl_pose_targets_and_lines_pin_the_planned_joints(cell):
    """E6POS with S and T: the TCP's pose under $TOOL, and among all IK solutions of that
    pose exactly one has the target's S and T: the planned one. The tool frame is the TCP in
    KUKA's flange frame, whose X axis is ROS-Industrial tool0's z (kuka_kr6_support:
    flange → tool0 turns 90° about y)."""
    tool = '{"shape": "cylinder", "size": [0.01, 0.1], "tcp": {"pos": [0, 0, 0.1]}}'
    result = _planned(["--arm", "kuka_kr6_r700", "--waypoints",
                       "examples/deburring_passes.csv", "--tool", tool, "--out", "p.csv"])
    src, dat = krl(result, "deburr", targets="poses", linear=True)
    moves = _parse(src, KRL_SRC, KRL_SRC_ORDER, newline="\r\n")
    decls = _parse(dat, KRL_DAT, KRL_DAT_ORDER, newline="\r\n")
    kinds = [groups[0] for rule, groups in moves if rule == "move"]
    assert kinds == ["PTP"] + ["LIN"] * 61  # one segment: every process move a line
    assert refused_lines(result) == []
    tool_frame = _kuka_pose(next(groups for rule, groups in decls if rule == "frame"))
    flange_to_tool0 = rot_y(math.radians(90.0))  # kuka_kr6_support's rpy (0, 90°, 0)
    tcp, tool0 = np.eye(4), np.eye(4)
    tcp[2, 3] = 0.1
    tool0[:3, :3] = flange_to_tool0
    np.testing.assert_allclose(tool_frame, tool0 @ tcp, atol=1e-9)
    arm = make_arm("kuka_kr6_r700")
    targets = {groups[0]: groups[1:] for rule, groups in decls if rule == "e6pos"}
    assert len(targets) == 62
    for i, step in enumerate(result.chosen_run.reached):
        groups = targets[f"XP{i}"]
        tcp_pose = _kuka_pose(groups[:6])
        flange_kuka = tcp_pose @ np.linalg.inv(tool_frame)
        fk_pose = flange_kuka @ tool0  # the fk frame is tool0
        q = _only_solution(arm, fk_pose, (int(groups[6]), int(groups[7])), kuka_status_turn)
        np.testing.assert_allclose(q, step.q, atol=1e-8)


def test_rapid_robtargets_and_lines_pin_the_planned_joints(cell):
    """robtarget with confdata under ConfJ/ConfL \\On: the TCP's pose under tPlan, and
    exactly one IK solution of it has the target's cf1, cf4, cf6, cfx: the planned one."""
    result = _planned(["--arm", "abb_irb2400", "--waypoints", "examples/welding_seam.csv",
                       "--scene", "examples/welding_cell.xml", "--tool",
                       "examples/welding_torch.json", "--out", "w.csv"])
    text = rapid(result, "weld_seam", targets="poses", linear=True)
    parsed = _parse(text, RAPID, RAPID_ORDER)
    moves = [groups for rule, groups in parsed if rule == "move"]
    assert [m[0] for m in moves] == ["MoveJ"] + ["MoveL"] * 8  # the seam: lines
    assert refused_lines(result) == []
    tool = next(groups for rule, groups in parsed if rule == "tool")
    tcp = np.eye(4)
    tcp[:3, :3] = quaternion_matrix(np.array([float(v) for v in tool[3:]]))
    tcp[:3, 3] = np.array([float(v) for v in tool[:3]]) / 1000.0
    np.testing.assert_allclose(tcp, Tool.from_spec(json.loads(
        (cell / "examples" / "welding_torch.json").read_text())).tcp, atol=1e-9)
    arm = make_arm("abb_irb2400")
    targets = {groups[0]: groups[1:] for rule, groups in parsed if rule == "robtarget"}
    for i, step in enumerate(result.chosen_run.reached):
        groups = targets[f"p{i}"]
        pose = np.eye(4)
        pose[:3, :3] = quaternion_matrix(np.array([float(v) for v in groups[3:7]]))
        pose[:3, 3] = np.array([float(v) for v in groups[:3]]) / 1000.0
        q = _only_solution(arm, pose @ np.linalg.inv(tcp), [int(v) for v in groups[7:]],
                           abb_confdata)
        np.testing.assert_allclose(q, step.q, atol=1e-8)


def test_urscript_poses_lines_and_refused_lines(tmp_path, monkeypatch):
    """movel and get_inverse_kin targets are the planned TCP poses (p[x, y, z, rx, ry, rz]
    under set_tcp); moves whose line cannot be followed stay joint moves and are named."""
    monkeypatch.chdir(tmp_path)
    generated = IKBranchEnv(arm="ur5e", scene="empty", task="random", n_waypoints=5)
    generated.reset(seed=4)
    arm = make_arm("ur5e")
    poses = np.array(generated.task.poses)
    step = poses[-1].copy()
    step[:3, 3] += [0.0, 0.0, 0.02]  # a last process move 20 mm straight up
    path = write_waypoints(tmp_path / "job.csv", np.concatenate([poses, step[None]]))
    result = _planned(["--arm", "ur5e", "--waypoints", str(path), "--out", "plan.csv",
                       "--max-joint-step", "off"])
    text = urscript(result, "ur_job", targets="poses", linear=True)
    parsed = _parse(text, URSCRIPT, URSCRIPT_ORDER)
    moves = [(rule, groups) for rule, groups in parsed if rule.startswith("move")]
    assert moves[-1][0] == "movel" and moves[0][0] == "movej_pose"
    refused = refused_lines(result)
    assert len(refused) == sum(rule == "movej_pose" for rule, _ in moves) - 1 and refused
    for (rule, groups), planned in zip(moves, result.chosen_run.reached, strict=True):
        values = [float(v) for v in groups]
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_rotvec(values[3:6]).as_matrix()
        pose[:3, 3] = values[:3]
        np.testing.assert_allclose(pose, arm.fk(planned.q), atol=1e-9)
        if rule == "movej_pose":
            np.testing.assert_allclose(values[6:], planned.q, atol=1e-9)
