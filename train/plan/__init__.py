"""``ikbranch plan``: which IK branch to take at each pose of a real job, priced and checked.

    ikbranch plan --arm anthropomorphic --waypoints examples/paper_worked_example.csv \\
        --out plan.csv [--json plan.json] [--gif plan.gif]
    ikbranch plan --arm abb_irb2400 --waypoints examples/welding_seam.csv \\
        --scene examples/welding_cell.xml --tool examples/welding_torch.json \\
        --planner dp_oracle --planner paper_rule --out weld.csv

The waypoints (a waypoint file, ``docs/files.md``) become one ``task="file"`` episode of
an :class:`~envs.ik_branch_env.IKBranchEnv`; each ``--planner`` plays it deterministically
in its own fresh env, and the DP oracle always plays it too, for the optimum. The first
``--planner``'s plan is written to ``--out`` (one row per waypoint: branch, label, joint
values in rad/m and in deg/mm, travel, time, collision flag, cumulative travel), the
table of every planner beside the optimum is printed, ``--json`` holds everything and
``--gif`` animates the plan. ``docs/plan.md`` describes the columns, frames and units.

Process continuity: the waypoints form process segments (the file's ``segment`` column or
blank lines, or ``--segments``; by default the whole file is one segment), inside which no
move may change the arm's configuration or step a joint by more than ``--max-joint-step``
(degrees; default ``auto``, derived from the job; ``off`` allows anything). Every planner
keeps that; the moves between segments may reconfigure and are flagged.

Poses are of the arm's ``fk`` frame, or of the tool's TCP with ``--tool``; in the arm's
base frame, or in the cell frame with ``--scene`` (its ``arm_base`` site or
``--scene-options`` place the arm). ``--start free`` (default): the arm is taken to stand
at the first waypoint already, in whichever branch is chosen, at no cost (the paper's
convention); ``--start home`` or ``--start Q1,Q2,…`` (rad/m; ``--start-degrees``: deg/mm):
the first move starts there.

Exit status: 0 the plan of the first planner reaches every waypoint without a collision;
3 it was written but does not (a collision, an invalid branch, or the episode ended
early: see the message); 2 bad input (a clear message, nothing written); 1 an internal
error.
"""

from .animation import Frame, animation_frames, render_frames
from .cli import EXIT_INPUT, EXIT_INTERNAL, EXIT_OK, EXIT_UNSAFE, main, parser
from .outputs import plan_csv, plan_json, summary, summary_table
from .playing import Plan, PlanRun, ProcessMove, Step, plan, play
from .request import PlanInputError, PlanRequest, parse_tool, request_from_args

__all__ = [
    "EXIT_INPUT", "EXIT_INTERNAL", "EXIT_OK", "EXIT_UNSAFE", "Frame", "Plan", "PlanInputError",
    "PlanRequest", "PlanRun", "ProcessMove", "Step", "animation_frames", "main", "parse_tool",
    "parser", "plan", "plan_csv", "plan_json", "play", "render_frames", "request_from_args",
    "summary", "summary_table",
]
