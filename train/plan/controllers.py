"""Programs a robot controller runs: the chosen plan as joint moves, in KUKA KRL, ABB
RAPID or URScript (``--krl``, ``--rapid``, ``--urscript``; ``docs/plan.md``).

Every target is the plan's joint configuration itself (KRL ``E6AXIS``, RAPID
``jointtarget``, URScript's joint list), moved to by a joint move (KRL ``PTP``, RAPID
``MoveAbsJ``, URScript ``movej``): the path the plan was collision-checked along, with no
configuration for the controller to choose. Values are the controller's own joint values
(the OPW arms' are opw_kinematics', which are the controller's; UR's are UR's), in
degrees (KRL, RAPID) or radians (URScript), with enough digits to round-trip to 1e-9.
Each file names the plan, the planner and the waypoints in comments (ASCII only: KRL
files are read as Windows-1252).
"""

from __future__ import annotations

import math
import re

from .playing import Plan, PlanRun

#: Which arms each language drives (``Arm.name`` prefixes).
FAMILIES = {"krl": ("kuka_",), "rapid": ("abb_",), "urscript": ("ur",)}
#: The file name each takes.
SUFFIXES = {"krl": ".src", "rapid": ".mod", "urscript": ".script"}
#: KRL and RAPID names: a letter, then letters, digits and underscores; at most 24
#: characters (KRL's limit; RAPID allows 32).
NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,23}")
#: Joint-value digits: 9 decimals of a degree (KRL, RAPID) or of a radian (URScript).
DECIMALS = 9


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


def _ascii(text: str) -> str:
    """``text`` for a comment: ASCII, no line breaks."""
    flat = " ".join(text.split())
    return flat.encode("ascii", "replace").decode("ascii")


def _degrees(value: float) -> str:
    return f"{math.degrees(value):.{DECIMALS}f}"


def _header(plan: Plan, run: PlanRun, comment: str) -> list[str]:
    return [f"{comment} ikbranch plan: {_ascii(plan.arm.name)}, planner {_ascii(run.name)}, "
            f"{len(run.reached)} joint moves",
            f"{comment} every move a joint move between the planned configurations, as the "
            "plan was collision-checked"]


def krl(plan: Plan, name: str, run: PlanRun | None = None) -> tuple[str, str]:
    """(``.src``, ``.dat``) of a KRL program ``name``: ``PTP`` to one ``E6AXIS`` a row."""
    run = plan.chosen_run if run is None else run
    src = ["DEF " + name + "( )", *("  " + line for line in _header(plan, run, ";"))]
    dat = [f"DEFDAT {name} PUBLIC"]
    for i, step in enumerate(run.reached):
        point = f"XP{i}"
        axes = ",".join(f"A{j + 1} {_degrees(v)}" for j, v in enumerate(step.q))
        externals = ",".join(f"E{j} 0.0" for j in range(1, 7))
        dat.append(f"  DECL E6AXIS {point}={{{axes},{externals}}}")
        src.append(f"  PTP {point} ; waypoint {step.waypoint}: "
                   f"{_ascii(plan.names[step.waypoint])}")
    src.append("END")
    dat.append("ENDDAT")
    return "\r\n".join(src) + "\r\n", "\r\n".join(dat) + "\r\n"


def rapid(plan: Plan, name: str, run: PlanRun | None = None) -> str:
    """A RAPID module ``name``: one ``jointtarget`` a row, ``MoveAbsJ`` to each (``fine``
    stops, ``v100``, ``tool0``: speeds and tool are the cell's to set)."""
    run = plan.chosen_run if run is None else run
    lines = [f"MODULE {name}", *("  " + line for line in _header(plan, run, "!"))]
    for i, step in enumerate(run.reached):
        axes = ",".join(_degrees(v) for v in step.q)
        lines.append(f"  CONST jointtarget jt{i}:=[[{axes}],[9E9,9E9,9E9,9E9,9E9,9E9]];")
    lines.append("  PROC main()")
    for i, step in enumerate(run.reached):
        lines.append(f"    MoveAbsJ jt{i},v100,fine,tool0; ! waypoint {step.waypoint}: "
                     f"{_ascii(plan.names[step.waypoint])}")
    lines += ["  ENDPROC", "ENDMODULE"]
    return "\n".join(lines) + "\n"


def urscript(plan: Plan, name: str, run: PlanRun | None = None) -> str:
    """A URScript program ``name``: ``movej`` to each row's joint list (rad), UR's default
    joint acceleration and speed (a = 1.4 rad/s², v = 1.05 rad/s)."""
    run = plan.chosen_run if run is None else run
    lines = [f"def {name}():", *("  " + line for line in _header(plan, run, "#"))]
    for step in run.reached:
        joints = ", ".join(f"{v:.{DECIMALS}f}" for v in step.q)
        lines.append(f"  movej([{joints}], a=1.4, v=1.05)  # waypoint {step.waypoint}: "
                     f"{_ascii(plan.names[step.waypoint])}")
    lines.append("end")
    return "\n".join(lines) + "\n"
