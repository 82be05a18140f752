"""Controller programs of ``ikbranch plan`` (train/plan/controllers.py): each file parsed
by a grammar of the language's forms it uses (KRL ``DEF``/``DEFDAT`` with ``E6AXIS`` and
``PTP``; RAPID ``MODULE`` with ``jointtarget`` and ``MoveAbsJ``; URScript ``def`` with
``movej``), and its targets read back equal to the plan's joint values."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.tasks.waypoint_file import write_waypoints
from ikbranch_gym.train.plan import EXIT_INPUT, EXIT_OK, main
from tests.train.test_plan import EXAMPLES, rows_of

NUMBER = r"-?\d+(?:\.\d+)?(?:E\d+)?"
NAME = r"[A-Za-z][A-Za-z0-9_]{0,23}"
COMMENT = r"[\x20-\x7e]*"  # printable ASCII

KRL_SRC = {
    "def": re.compile(rf"DEF ({NAME})\( \)"),
    "comment": re.compile(rf"  ;{COMMENT}"),
    "ptp": re.compile(rf"  PTP ({NAME})(?: ;{COMMENT})?"),
    "end": re.compile(r"END"),
}
KRL_DAT = {
    "defdat": re.compile(rf"DEFDAT ({NAME}) PUBLIC"),
    "decl": re.compile(rf"  DECL E6AXIS ({NAME})=\{{"
                       + ",".join(rf"A{j} ({NUMBER})" for j in range(1, 7)) + ","
                       + ",".join(rf"E{j} {NUMBER}" for j in range(1, 7)) + r"\}"),
    "enddat": re.compile(r"ENDDAT"),
}
RAPID = {
    "module": re.compile(rf"MODULE ({NAME})"),
    "comment": re.compile(rf"  !{COMMENT}"),
    "const": re.compile(rf"  CONST jointtarget ({NAME}):=\[\["
                        + ",".join([rf"({NUMBER})"] * 6) + r"\],\[(?:9E9,){5}9E9\]\];"),
    "proc": re.compile(r"  PROC main\(\)"),
    "move": re.compile(rf"    MoveAbsJ ({NAME}),v100,fine,tool0;(?: !{COMMENT})?"),
    "endproc": re.compile(r"  ENDPROC"),
    "endmodule": re.compile(r"ENDMODULE"),
}
URSCRIPT = {
    "def": re.compile(rf"def ({NAME})\(\):"),
    "comment": re.compile(rf"  #{COMMENT}"),
    "movej": re.compile(r"  movej\(\[" + ", ".join([rf"({NUMBER})"] * 6)
                        + rf"\], a=1\.4, v=1\.05\)(?:  #{COMMENT})?"),
    "end": re.compile(r"end"),
}


def _parse(text: str, grammar: dict[str, re.Pattern], order: list[str],
           newline: str = "\n") -> list[tuple[str, tuple[str, ...]]]:
    """Each line matched by exactly the rules ``order`` allows in sequence: the first
    rule once, then body rules, then the closing rules once each, in order."""
    assert text.endswith(newline) and text.isascii()
    lines = text[: -len(newline)].split(newline)
    assert all("\r" not in line and "\n" not in line for line in lines)
    parsed = []
    for line in lines:
        matches = [rule for rule, pattern in grammar.items() if pattern.fullmatch(line)]
        assert len(matches) == 1, (line, matches)
        parsed.append((matches[0], grammar[matches[0]].fullmatch(line).groups()))
    rules = [rule for rule, _ in parsed]
    position = 0
    for rule in rules:  # the rules appear in the allowed order (repeats allowed)
        while order[position] != rule:
            position += 1
            assert position < len(order), rules
    assert rules[0] == order[0] and rules[-1] == order[-1]
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
    moves = _parse(src, KRL_SRC, ["def", "comment", "ptp", "end"], newline="\r\n")
    decls = _parse(dat, KRL_DAT, ["defdat", "decl", "enddat"], newline="\r\n")
    assert moves[0][1] == ("deburr",) and decls[0][1] == ("deburr",)
    targets = {groups[0]: np.radians([float(v) for v in groups[1:]])
               for rule, groups in decls if rule == "decl"}
    order = [groups[0] for rule, groups in moves if rule == "ptp"]
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
    parsed = _parse(text, RAPID, ["module", "comment", "const", "proc", "move", "endproc",
                                  "endmodule"])
    assert parsed[0][1] == ("weld_seam",)
    targets = {groups[0]: np.radians([float(v) for v in groups[1:]])
               for rule, groups in parsed if rule == "const"}
    order = [groups[0] for rule, groups in parsed if rule == "move"]
    assert len(order) == 9 and set(order) == set(targets)
    np.testing.assert_allclose(np.array([targets[name] for name in order]),
                               _joint_rows(cell / "weld.csv"), rtol=0,
                               atol=math.radians(1e-9))
    # The torch's j6 turns beyond −180° on this seam: written as the branch has it.
    assert min(targets[name][5] for name in order) < -math.pi


def test_urscript_program_of_a_ur5e_job(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    generated = IKBranchEnv(arm="ur5e", scene="empty", task="random", n_waypoints=5)
    generated.reset(seed=4)
    path = write_waypoints(tmp_path / "job.csv", generated.task.poses, names=[
        "pick", "über", "place", "a\nb", "home"])
    assert main(["--arm", "ur5e", "--waypoints", str(path), "--out", "plan.csv",
                 "--max-joint-step", "off", "--urscript", "ur_job.script"]) == EXIT_OK
    text = (tmp_path / "ur_job.script").read_text(encoding="ascii")
    parsed = _parse(text, URSCRIPT, ["def", "comment", "movej", "end"])
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
