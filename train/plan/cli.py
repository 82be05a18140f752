"""``ikbranch plan``'s command line: the parser, the run, the exit status."""

from __future__ import annotations

import argparse
import json
import math
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ikbranch_gym.agents.evaluation import ORACLE
from ikbranch_gym.envs.files import write_all_atomically

from . import __doc__ as DESCRIPTION
from .animation import animation_frames, gif_bytes, render_frames
from .chart import map_png
from .controllers import TARGETS, krl, rapid, refused_lines, urscript
from .outputs import plan_csv, plan_json, summary_table
from .playing import Plan, plan
from .request import PLANNERS, PlanInputError, output_paths, request_from_args

if TYPE_CHECKING:
    pass

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_UNSAFE = 0, 1, 2, 3


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="ikbranch plan", description=DESCRIPTION,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--arm", required=True, help="an arm name (envs.kinematics.ARM_NAMES)")
    p.add_argument("--arm-params", metavar="JSON", help="arm parameters (make_arm), a JSON object")
    p.add_argument("--waypoints", required=True, metavar="FILE",
                   help="waypoint file, CSV or JSON (docs/files.md)")
    p.add_argument("--points-abc", type=float, nargs=3, metavar=("A", "B", "C"),
                   help="four-point files: a, b, c in mm (when the file has no a,b,c columns)")
    p.add_argument("--units", choices=("m", "mm"),
                   help="the unit of the file's x, y, z (default: m, or mm for the KUKA and "
                        "ABB formats)")
    p.add_argument("--extra-columns", metavar="C1,C2,…",
                   help="further columns of the waypoint file, passed through to the plan")
    p.add_argument("--scene", metavar="FILE",
                   help="MJCF scene file of the cell (default: the empty scene, floor only)")
    p.add_argument("--scene-options", metavar="JSON",
                   help="JSON object: base_pos, base_quat | base_rpy, floor, decompose, "
                        "coacd_options")
    p.add_argument("--tool", metavar="JSON|FILE",
                   help="the held tool: JSON text or a JSON file (envs/tools.py); waypoints "
                        "then target its TCP")
    p.add_argument("--start", default="free", metavar="free|home|Q",
                   help="free (default: the first branch at no cost), home, or "
                        "comma-separated joint values in rad/m (--start=-0.1,… for a "
                        "leading minus sign also works)")
    p.add_argument("--start-degrees", action="store_true",
                   help="--start values are in degrees (revolute) and mm (prismatic)")
    p.add_argument("--planner", action="append", dest="planners", metavar="NAME|MODEL.zip",
                   help=f"repeatable: {', '.join(PLANNERS)} (receding_dp:H, fixed:BRANCH, "
                        "random:SEED) or an SB3 model zip; the first is written to --out "
                        "(default dp_oracle); the DP oracle always runs")
    p.add_argument("--segments", metavar="W1,W2,…",
                   help="the 0-based waypoints where process segments begin (default: the "
                        "file's segment column or blank lines; without them one segment)")
    p.add_argument("--max-joint-step", default="auto", metavar="DEG|auto|off",
                   help="inside a segment no move may change the configuration or step a "
                        "joint by more than this (degrees; auto: twice the least step the "
                        "hardest segment needs, 10–179; off: no continuity)")
    p.add_argument("--singularity-margin", type=float, default=5.0, metavar="DEG",
                   help="flag rows whose wrist or elbow lies this near a singular "
                        "configuration (degrees, default 5; OPW and UR arms)")
    p.add_argument("--shoulder-margin", type=float, default=20.0, metavar="MM",
                   help="flag rows whose wrist point lies this near the shoulder "
                        "singularity (mm, default 20)")
    p.add_argument("--avoid-singularities", action="store_true",
                   help="no planner may take a branch within those margins")
    p.add_argument("--allow-contact", action="append", dest="allowed_contacts",
                   metavar="A:B",
                   help="repeatable: two geom names (fnmatch patterns, e.g. tool:scene/part*) "
                        "that may touch; every other pair is still checked")
    p.add_argument("--skip-unreachable", action="store_true",
                   help="leave out the rows no branch reaches (each named on stderr) and "
                        "plan the rest")
    p.add_argument("--tool-axis", metavar="RANGE:STEP",
                   help="a round tool free about its TCP z axis: every STEP degrees within "
                        "±RANGE (e.g. 180:15); the plan chooses the angle with the branch")
    p.add_argument("--tool-tilt", metavar="CONE:STEP",
                   help="the tool's axis may also tilt by up to CONE degrees in any "
                        "direction, sampled every STEP degrees (e.g. 10:5)")
    p.add_argument("--line-tolerance", type=float, default=1.0, metavar="MM",
                   help="flag moves inside a segment whose TCP leaves the straight line by "
                        "more than this (mm, default 1)")
    p.add_argument("--joint-speeds", metavar="rated|generic|V1,…",
                   help="the joint speeds moves are timed at: rated (the arm's data sheet; "
                        "the default where there is one), generic (1.5 rad/s, 0.5 m/s) or "
                        "one speed per joint (deg/s, mm/s)")
    p.add_argument("--resolution", type=float, default=0.01, metavar="M",
                   help="collision-check clearance and step along paths (m, default 0.01)")
    p.add_argument("--env-kwargs", metavar="JSON",
                   help="further IKBranchEnv arguments, e.g. {\"time_weight\": 1, "
                        "\"lookahead\": 2, \"observation\": \"ladder\"} (for a model)")
    p.add_argument("--out", required=True, metavar="plan.csv", help="the plan (CSV)")
    p.add_argument("--json", metavar="FILE", help="everything, as JSON")
    p.add_argument("--gif", metavar="FILE", help="an animation of the plan")
    p.add_argument("--krl", metavar="NAME.src",
                   help="a KUKA KRL program of the plan (NAME.src and NAME.dat: PTP to "
                        "E6AXIS targets)")
    p.add_argument("--rapid", metavar="NAME.mod",
                   help="an ABB RAPID module of the plan (MoveAbsJ to jointtargets)")
    p.add_argument("--urscript", metavar="NAME.script",
                   help="a URScript program of the plan (movej to joint lists)")
    p.add_argument("--program-targets", choices=TARGETS, default="joints",
                   help="the programs' targets: joints (E6AXIS, jointtarget, joint lists; "
                        "default) or poses (E6POS with S and T, robtarget with confdata, "
                        "p[…] solved nearest the planned joints); joint moves either way")
    p.add_argument("--lin", action="store_true",
                   help="the programs move linearly (LIN, MoveL, movel) inside process "
                        "segments, each line checked first (IK along it, collisions); "
                        "a move whose line fails stays a joint move, named on stderr")
    p.add_argument("--map", metavar="FILE",
                   help="a PNG map: waypoints × branches coloured by state, the plan drawn")
    p.add_argument("--gif-size", type=int, nargs=2, default=(480, 360),
                   metavar=("W", "H"), help="GIF frame size in pixels (480 360)")
    p.add_argument("--gif-fps", type=float, default=12.0,
                   help="GIF frames per second along a move (12)")
    p.add_argument("--gif-hold", type=float, default=0.5, metavar="S",
                   help="GIF: how long each waypoint is held (s, 0.5)")
    p.add_argument("--gif-speed", type=float, default=1.0,
                   help="GIF playback speed: 1 is real time at the --joint-speeds (1)")
    return p


def _join_negative_start(argv: list[str]) -> list[str]:
    """``--start -0.5,1,…`` as ``--start=-0.5,1,…`` (argparse takes a leading minus for an
    option)."""
    out, i = [], 0
    while i < len(argv):
        value = argv[i + 1] if i + 1 < len(argv) else ""
        if argv[i] == "--start" and value[:1] == "-" and (value[1:2].isdigit()
                                                          or value[1:2] == "."):
            out.append(f"--start={argv[i + 1]}")
            i += 2
            continue
        out.append(argv[i])
        i += 1
    return out


def _fail(message: str) -> int:
    print(f"ikbranch plan: error: {message}", file=sys.stderr)
    return EXIT_INPUT


def _check_program_form(args: argparse.Namespace, outputs: dict[str, Path]) -> None:
    """``--lin`` and ``--program-targets`` only with a program to shape."""
    programs = [o for o in ("--krl", "--rapid", "--urscript") if o in outputs]
    for option, given in (("--lin", args.lin),
                          ("--program-targets", args.program_targets != "joints")):
        if given and not programs:
            raise PlanInputError(f"{option} shapes a controller program: give --krl, "
                                 "--rapid or --urscript")


def _warn_off_line(result: Plan) -> None:
    """A warning on stderr naming the chosen plan's moves that leave the straight line."""
    chosen = result.chosen_run
    off_line = [(step.waypoint, move.line_deviation or 0.0) for step, move in
                zip(chosen.reached, result.moves(chosen), strict=True) if move.off_line]
    if off_line:
        waypoint, worst = max(off_line, key=lambda item: item[1])
        print(f"ikbranch plan: warning: {len(off_line)} moves inside process segments leave "
              f"the straight line by more than {1000 * result.line_tolerance:g} mm (the most, "
              f"{1000 * worst:.2f} mm, into waypoint {waypoint}): moved in joint space, as "
              "the plan is checked, the tool does not follow the line there; add points, or "
              "write the program with --lin (linear moves, each line checked)", file=sys.stderr)


def _outputs(result: Plan, outputs: dict[str, Path], args: argparse.Namespace,
             argv: Sequence[str]) -> dict[Path, bytes]:
    """The content of every requested output file."""
    files = {outputs["--out"]: plan_csv(result).encode("utf-8")}
    if "--json" in outputs:
        record = plan_json(result, argv)
        files[outputs["--json"]] = (json.dumps(record, indent=1, allow_nan=False)
                                    + "\n").encode("utf-8")
    if "--gif" in outputs:
        width, height = args.gif_size
        frames = animation_frames(result, fps=args.gif_fps, speed=args.gif_speed,
                                  hold=args.gif_hold)
        images = render_frames(result, frames, width, height)
        files[outputs["--gif"]] = gif_bytes(images, [f.duration for f in frames])
    if "--map" in outputs:
        files[outputs["--map"]] = map_png(result)
    form = {"targets": args.program_targets, "linear": args.lin}
    if "--krl" in outputs:
        src, dat = krl(result, outputs["--krl"].stem, **form)
        files[outputs["--krl"]] = src.encode("ascii")
        files[outputs["--krl (.dat)"]] = dat.encode("ascii")
    if "--rapid" in outputs:
        files[outputs["--rapid"]] = rapid(result, outputs["--rapid"].stem, **form).encode(
            "ascii")
    if "--urscript" in outputs:
        files[outputs["--urscript"]] = urscript(result, outputs["--urscript"].stem,
                                                **form).encode("ascii")
    return files


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser().parse_args(_join_negative_start(argv))
    try:
        width, height = args.gif_size
        if width < 16 or height < 16:
            raise PlanInputError(f"--gif-size must be at least 16 16, got {width} {height}")
        for option, value in (("--gif-fps", args.gif_fps), ("--gif-speed", args.gif_speed),
                              ("--gif-hold", args.gif_hold)):
            if not (math.isfinite(value) and value > 0):
                raise PlanInputError(f"{option} must be a positive number, got {value!r}")
        request = request_from_args(args)
        outputs = output_paths(args, request)
        _check_program_form(args, outputs)
        result = plan(request)
        files = _outputs(result, outputs, args, argv)
        write_all_atomically(files)  # every file or none
    except PlanInputError as exc:
        return _fail(str(exc))
    except ValueError as exc:  # the env's and the planners' checks of the inputs
        message = str(exc)
        if message.startswith("process segment"):
            message += (" (segments: --segments, a blank line or a segment column in the "
                        "file; --max-joint-step DEG raises the limit, off plans without "
                        "process continuity)")
        return _fail(message)
    except OSError as exc:
        return _fail(f"cannot write the outputs: {exc}")
    except Exception:  # a bug: say so, with the traceback to report
        print("ikbranch plan: internal error (please report it with this traceback):",
              file=sys.stderr)
        traceback.print_exc()
        return EXIT_INTERNAL
    print(summary_table(result))
    chosen = result.chosen_run
    print(f"\n* {chosen.name}: {len(chosen.reached)} of {chosen.n_waypoints} waypoints, "
          f"travel {math.degrees(chosen.travel):.2f}°, written to "
          + ", ".join(str(path) for path in files))
    _warn_off_line(result)
    refused = refused_lines(result) if args.lin else []
    if refused:
        print(f"ikbranch plan: warning: {len(refused)} process moves stay joint moves in the "
              "program (--lin): their line fails the check:\n  " + "\n  ".join(refused),
              file=sys.stderr)
    if result.skipped:
        print(f"ikbranch plan: warning: {len(result.skipped)} rows no branch reaches were "
              "left out (--skip-unreachable):\n  " + "\n  ".join(result.skipped),
              file=sys.stderr)
    if not chosen.success:
        optimum = result.optimum
        note = "" if optimum.success else (
            f"; even {ORACLE} finds no collision-free plan ({optimum.problem()})")
        print(f"ikbranch plan: warning: the plan of {chosen.name} is not safe to run: "
              f"{chosen.problem()}{note}", file=sys.stderr)
        return EXIT_UNSAFE
    return EXIT_OK
