"""Programs a robot controller runs: the chosen plan in KUKA KRL, ABB RAPID or URScript
(``--krl``, ``--rapid``, ``--urscript``; ``docs/plan.md``).

**Targets** (``--program-targets``):

- ``joints`` (default): every target is the plan's joint configuration itself (KRL
  ``E6AXIS``, RAPID ``jointtarget``, URScript's joint list), moved to by a joint move
  (``PTP``, ``MoveAbsJ``, ``movej``): the path the plan was collision-checked along, with no
  configuration for the controller to choose.
- ``poses``: every target is the TCP's pose in the robot's base frame with the
  configuration that pins the plan's joint values (KRL ``E6POS`` with Status and Turn,
  RAPID ``robtarget`` with ``confdata`` under ``ConfJ \\On``, URScript ``p[…]`` solved by
  ``get_inverse_kin`` nearest the planned joints), still moved to by joint moves: the same
  configurations, the same checked paths, and targets an engineer can touch up.

**Linear moves** (``--lin``): inside a process segment each move is the controller's
linear move (``LIN``, ``MoveL``, ``movel``) to a pose target, after the plan has checked
it (``Plan.linear_moves``: IK along the line in the move's configuration, the joint moves
between those samples collision-checked); the first move, air moves and a move whose line
fails the check stay joint moves to ``--program-targets`` targets (``--lin`` names those
on stderr).

The program carries the TCP it was planned with, in the controller's own flange frame:
KRL ``$TOOL`` (KUKA's flange frame has its X axis out of the flange; the plan's fk frame,
opw_kinematics' and ROS-Industrial's ``tool0``, its z axis: ``$TOOL`` = Ry(90°)·TCP, the
turn ROS-Industrial's ``kuka_kr6_support`` puts between ``flange`` and ``tool0``), a RAPID
``tooldata`` (ABB's ``tool0`` is the fk frame; its load is ``load0``'s until the cell sets
the tool's mass), URScript ``set_tcp`` (UR's flange frame is the fk frame); ``$BASE`` and
``wobj0`` are the robot's base frame. Values are the controller's (joint values: the OPW
arms' are opw_kinematics', which are the controller's; UR's are UR's), in degrees and mm
(KRL, RAPID) or radians and metres (URScript), with enough digits to round-trip to 1e-9.
Each file names the plan, the planner and the waypoints in comments (ASCII only: KRL files
are read as Windows-1252).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ikbranch_gym.envs.kinematics.rotations import (
    rot_y,
    rotation_to_quaternion,
    rotation_vector,
    zyx_angles,
)

from .playing import Plan, PlanRun, Step

#: Which arms each language drives (``Arm.name`` prefixes).
FAMILIES = {"krl": ("kuka_",), "rapid": ("abb_",), "urscript": ("ur",)}
#: The file name each takes.
SUFFIXES = {"krl": ".src", "rapid": ".mod", "urscript": ".script"}
#: KRL and RAPID names: a letter, then letters, digits and underscores; at most 24
#: characters (KRL's limit; RAPID allows 32).
NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,23}")
#: Digits: 9 decimals of a degree or mm (KRL, RAPID), of a radian or metre (URScript).
DECIMALS = 9
TARGETS = ("joints", "poses")
#: KUKA's flange frame in the fk frame: its X axis is the fk frame's z (out of the flange).
KUKA_FLANGE = rot_y(-math.pi / 2)


def check_family(language: str, arm_name: str) -> None:
    """``ValueError`` unless ``language`` drives ``arm_name``."""
    if not arm_name.startswith(FAMILIES[language]):
        makers = {"krl": "a KUKA", "rapid": "an ABB", "urscript": "a Universal Robots"}
        raise ValueError(f"--{language}: {makers[language]} program needs "
                         f"{makers[language]} arm, not {arm_name}")


def program_name(stem: str, option: str) -> str:
    """The module / program name of an output file's stem; ``ValueError`` if it is not a
    name the controller accepts."""
    if not NAME.fullmatch(stem):
        raise ValueError(f"{option}: the file name {stem!r} must be a controller name: a "
                         "letter, then letters, digits or underscores, at most 24")
    return stem


@dataclass(frozen=True)
class Motion:
    """One move of a program: into ``step`` as a ``kind`` move ("joint" or "linear") to a
    ``target`` of ``form`` ("joints" or "poses"); ``pose`` the TCP's (4, 4) there."""

    step: Step
    kind: str
    form: str
    pose: np.ndarray


def motions(plan: Plan, run: PlanRun, targets: str = "joints",
            linear: bool = False) -> list[Motion]:
    """The program's moves: each row of ``run`` a joint move to a ``targets`` target, or,
    with ``linear``, inside a segment a linear move wherever the plan's check lets it."""
    kinematic = getattr(plan.arm, "base_arm", plan.arm)
    tcp = _tcp(plan)
    lines = plan.linear_moves(run) if linear else [None] * len(run.reached)
    out = []
    for step, line in zip(run.reached, lines, strict=True):
        pose = kinematic.fk(step.q) @ tcp
        if line is not None and line.problem is None:
            out.append(Motion(step, "linear", "poses", pose))
        else:
            out.append(Motion(step, "joint", targets, pose))
    return out


def refused_lines(plan: Plan, run: PlanRun | None = None) -> list[str]:
    """Per process move whose line fails the check: which waypoint and why (``--lin``)."""
    run = plan.chosen_run if run is None else run
    return [f"waypoint {step.waypoint} ({_ascii(plan.names[step.waypoint])}): "
            f"{line.problem}; a joint move instead"
            for step, line in zip(run.reached, plan.linear_moves(run), strict=True)
            if line is not None and line.problem is not None]


def _ascii(text: str) -> str:
    """``text`` for a comment: ASCII, no line breaks."""
    flat = " ".join(text.split())
    return flat.encode("ascii", "replace").decode("ascii")


def _number(value: float) -> str:
    text = f"{value:.{DECIMALS}f}"
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text  # no −0


def _degrees(value: float) -> str:
    return _number(math.degrees(value))


def _mm(values: np.ndarray) -> list[str]:
    return [_number(1000.0 * v) for v in values]


def _header(plan: Plan, run: PlanRun, comment: str, moves: list[Motion]) -> list[str]:
    linear = sum(m.kind == "linear" for m in moves)
    what = ("every move a joint move between the planned configurations, as the plan was "
            "collision-checked") if linear == 0 else (
            f"{linear} linear moves inside process segments (checked along the line), the "
            "others joint moves between the planned configurations")
    return [f"{comment} ikbranch plan: {_ascii(plan.arm.name)}, planner {_ascii(run.name)}, "
            f"{len(run.reached)} moves", f"{comment} {what}",
            f"{comment} targets in the robot's base frame; the tool is the plan's TCP"]


def _tcp(plan: Plan) -> np.ndarray:
    return np.eye(4) if plan.tool is None else np.asarray(plan.tool.tcp)


def _kuka_frame(pose: np.ndarray) -> str:
    a, b, c = zyx_angles(pose[:3, :3])
    x, y, z = _mm(pose[:3, 3])
    return f"X {x},Y {y},Z {z},A {_degrees(a)},B {_degrees(b)},C {_degrees(c)}"


def krl(plan: Plan, name: str, run: PlanRun | None = None, targets: str = "joints",
        linear: bool = False) -> tuple[str, str]:
    """(``.src``, ``.dat``) of a KRL program ``name``: ``PTP`` to one ``E6AXIS`` or
    ``E6POS`` (with S and T) a row, ``LIN`` to ``E6POS`` for checked linear moves."""
    from .outputs import controller_values

    run = plan.chosen_run if run is None else run
    moves = motions(plan, run, targets, linear)
    tool = np.eye(4)
    tool[:3, :3] = KUKA_FLANGE.T
    tool = tool @ _tcp(plan)  # the TCP in KUKA's flange frame
    src = ["DEF " + name + "( )", *("  " + line for line in _header(plan, run, ";", moves)),
           "  $BASE=$NULLFRAME", "  $TOOL=TCP_PLAN"]
    dat = [f"DEFDAT {name} PUBLIC", f"  DECL FRAME TCP_PLAN={{{_kuka_frame(tool)}}}"]
    externals = ",".join(f"E{j} 0.0" for j in range(1, 7))
    for i, move in enumerate(moves):
        point = f"XP{i}"
        if move.form == "joints":
            axes = ",".join(f"A{j + 1} {_degrees(v)}" for j, v in enumerate(move.step.q))
            dat.append(f"  DECL E6AXIS {point}={{{axes},{externals}}}")
        else:
            status, turn = controller_values(plan.arm, move.step.q)
            dat.append(f"  DECL E6POS {point}={{{_kuka_frame(move.pose)},S {status},"
                       f"T {turn},{externals}}}")
        src.append(f"  {'LIN' if move.kind == 'linear' else 'PTP'} {point} ; waypoint "
                   f"{move.step.waypoint}: {_ascii(plan.names[move.step.waypoint])}")
    src.append("END")
    dat.append("ENDDAT")
    return "\r\n".join(src) + "\r\n", "\r\n".join(dat) + "\r\n"


def _rapid_pose(pose: np.ndarray) -> str:
    q = rotation_to_quaternion(pose[:3, :3])
    return f"[{','.join(_mm(pose[:3, 3]))}],[{','.join(_number(v) for v in q)}]"


def rapid(plan: Plan, name: str, run: PlanRun | None = None, targets: str = "joints",
          linear: bool = False) -> str:
    """A RAPID module ``name``: ``MoveAbsJ`` to ``jointtarget``s or ``MoveJ`` to
    ``robtarget``s (with ``confdata``), ``MoveL`` for checked linear moves (``fine`` stops,
    ``v100``: speeds are the cell's to set), all with the plan's ``tooldata`` ``tPlan``."""
    from .outputs import controller_values

    run = plan.chosen_run if run is None else run
    moves = motions(plan, run, targets, linear)
    lines = [f"MODULE {name}", *("  " + line for line in _header(plan, run, "!", moves)),
             "  ! tPlan: the plan's TCP; its load is load0's: set the tool's mass and "
             "centre of gravity before running",
             f"  PERS tooldata tPlan:=[TRUE,[{_rapid_pose(_tcp(plan))}],"
             "[0.001,[0,0,0.001],[1,0,0,0],0,0,0]];"]
    for i, move in enumerate(moves):
        if move.form == "joints":
            axes = ",".join(_degrees(v) for v in move.step.q)
            lines.append(f"  CONST jointtarget jt{i}:=[[{axes}],[9E9,9E9,9E9,9E9,9E9,9E9]];")
        else:
            conf = ",".join(str(v) for v in controller_values(plan.arm, move.step.q))
            lines.append(f"  CONST robtarget p{i}:=[{_rapid_pose(move.pose)},[{conf}],"
                         "[9E9,9E9,9E9,9E9,9E9,9E9]];")
    lines += ["  PROC main()", "    ConfJ \\On;", "    ConfL \\On;"]
    for i, move in enumerate(moves):
        where = f" ! waypoint {move.step.waypoint}: {_ascii(plan.names[move.step.waypoint])}"
        if move.form == "joints":
            lines.append(f"    MoveAbsJ jt{i},v100,fine,tPlan;{where}")
        else:
            instruction = "MoveL" if move.kind == "linear" else "MoveJ"
            lines.append(f"    {instruction} p{i},v100,fine,tPlan;{where}")
    lines += ["  ENDPROC", "ENDMODULE"]
    return "\n".join(lines) + "\n"


def _ur_pose(pose: np.ndarray) -> str:
    values = [*pose[:3, 3], *rotation_vector(pose[:3, :3])]
    return "p[" + ", ".join(_number(v) for v in values) + "]"


def urscript(plan: Plan, name: str, run: PlanRun | None = None, targets: str = "joints",
             linear: bool = False) -> str:
    """A URScript program ``name``: ``movej`` to each row's joint list (rad) or to its pose
    solved nearest the planned joints, ``movel`` for checked linear moves; UR's default
    accelerations and speeds (``movej`` a = 1.4 rad/s², v = 1.05 rad/s; ``movel``
    a = 1.2 m/s², v = 0.25 m/s)."""
    run = plan.chosen_run if run is None else run
    moves = motions(plan, run, targets, linear)
    lines = [f"def {name}():", *("  " + line for line in _header(plan, run, "#", moves)),
             f"  set_tcp({_ur_pose(_tcp(plan))})"]
    for move in moves:
        joints = "[" + ", ".join(_number(v) for v in move.step.q) + "]"
        where = f"  # waypoint {move.step.waypoint}: {_ascii(plan.names[move.step.waypoint])}"
        if move.kind == "linear":
            lines.append(f"  movel({_ur_pose(move.pose)}, a=1.2, v=0.25){where}")
        elif move.form == "poses":
            lines.append(f"  movej(get_inverse_kin({_ur_pose(move.pose)}, qnear={joints}), "
                         f"a=1.4, v=1.05){where}")
        else:
            lines.append(f"  movej({joints}, a=1.4, v=1.05){where}")
    lines.append("end")
    return "\n".join(lines) + "\n"
