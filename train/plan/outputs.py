"""What a plan writes: the CSV of the chosen planner, the summary table, the JSON with
everything (``docs/plan.md``, "Outputs")."""

from __future__ import annotations

import csv
import hashlib
import io
import math
import platform
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbranch_gym.agents.evaluation import ORACLE

from .playing import Plan, PlanRun, ProcessMove

if TYPE_CHECKING:
    from ikbranch_gym.envs.kinematics import Arm

#: Packages whose versions the JSON records.
VERSIONED = ("ikbranch-gym", "numpy", "mujoco", "gymnasium", "coacd", "numba")
FORMAT = "ikbranch-plan/2"


# --------------------------------------------------------------------------- outputs
def _unit_suffix(kind: str) -> str:
    return "mm" if kind == "prismatic" else "deg"


def _display(values: np.ndarray, kinds: Sequence[str]) -> list[float]:
    """Joint values in the degree column set: revolute in degrees, prismatic in mm."""
    return [float(np.degrees(v)) if kind != "prismatic" else float(v * 1000.0)
            for v, kind in zip(values, kinds, strict=True)]


def controller_columns(arm: Any) -> tuple[str, ...]:
    """The controller's configuration columns of ``arm``'s plans (KUKA, ABB; else none)."""
    name = getattr(arm, "base_arm", arm).name
    if name.startswith("kuka_"):
        return ("kuka_s", "kuka_t")
    if name.startswith("abb_"):
        return ("cf1", "cf4", "cf6", "cfx")
    return ()


def controller_values(arm: Any, q: np.ndarray) -> list[int]:
    """The row's values of :func:`controller_columns`
    (``envs.kinematics.controller_config``)."""
    from ikbranch_gym.envs.kinematics.controller_config import abb_confdata, kuka_status_turn

    base = getattr(arm, "base_arm", arm)
    columns = controller_columns(arm)
    if columns and columns[0] == "kuka_s":
        status, turn = kuka_status_turn(base, q)
        return [int(status), int(turn)]
    if columns:
        return [int(v) for v in abb_confdata(base, q)]
    return []


def csv_columns(arm: Arm, extra: Sequence[str] = ()) -> list[str]:
    names, kinds = arm.joint_names, arm.joint_types
    return (["waypoint", "row", "name", "segment", "branch", "label", "configuration",
             "turns", "tool_angle_deg", "tool_tilt_deg", "tool_tilt_azimuth_deg",
             *controller_columns(arm), *names,
             *(f"{n}_{_unit_suffix(k)}" for n, k in zip(names, kinds, strict=True)),
             "travel_rad", "travel_deg", "time_s", "collision", "max_step_deg", "air_move",
             "reconfiguration", "wrist_margin_deg", "elbow_margin_deg", "shoulder_margin_mm",
             "near_singularity", "line_deviation_mm", "line_rotation_deg", "off_line",
             "clearance_mm", "clearance_pair",
             "cumulative_travel_rad", "cumulative_travel_deg", *extra])


def turns(arm: Any, q: np.ndarray) -> str:
    """Each revolute joint's turn ``name:t``, t = ⌊(q + π) / 2π⌋ (0 in [−π, π), 1 a
    revolution on, −1 one back), space-separated in joint order: with ``configuration``,
    the controller-independent name of where the arm stands."""
    return " ".join(f"{name}:{math.floor((float(v) + math.pi) / (2.0 * math.pi))}"
                    for name, v, kind in zip(arm.joint_names, q, arm.joint_types, strict=True)
                    if kind == "revolute")


def tool_angle(arm: Any, branch: int) -> float:
    """The tool's angle about its axis in ``branch`` (rad; 0 without a free tool axis)."""
    angles = getattr(arm, "branch_angles", None)
    return 0.0 if angles is None else float(angles[branch])


def tool_tilt(arm: Any, branch: int) -> tuple[float, float]:
    """The tilt of the tool's axis in ``branch`` and its azimuth (rad; 0, 0 untilted)."""
    tilts = getattr(arm, "branch_tilts", None)
    if tilts is None:
        return 0.0, 0.0
    return float(tilts[branch]), float(arm.branch_azimuths[branch])


def _line(move: ProcessMove) -> list[str]:
    """The CSV's line cells of a row: mm, degrees, 0/1 (blank for an air move)."""
    if move.line_deviation is None or move.line_rotation is None:
        return ["", "", ""]
    return [repr(1000.0 * move.line_deviation), repr(math.degrees(move.line_rotation)),
            str(int(move.off_line))]


def _margins(move: ProcessMove) -> list[str]:
    """The CSV's singularity cells of a row: degrees, degrees, mm ("" without rules)."""
    if move.margins is None:
        return ["", "", ""]
    wrist, elbow, shoulder = move.margins
    return [repr(math.degrees(wrist)), repr(math.degrees(elbow)), repr(1000.0 * shoulder)]


def plan_csv(plan: Plan, run: PlanRun | None = None) -> str:
    """The plan of ``run`` (default the chosen planner's) as CSV text: one row per
    waypoint reached, every float as its shortest round-trip ``repr``."""
    run = plan.chosen_run if run is None else run
    arm = plan.arm
    buffer = io.StringIO(newline="")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(csv_columns(arm, list(plan.extras)))
    cumulative = 0.0
    for step, move, (gap, pair) in zip(run.reached, plan.moves(run), plan.clearances(run),
                                       strict=True):
        cumulative += step.travel
        writer.writerow([
            step.waypoint, plan.rows[step.waypoint], plan.names[step.waypoint], move.segment,
            step.branch, step.label,
            move.configuration, turns(arm, step.q),
            repr(math.degrees(tool_angle(arm, step.branch))),
            *(repr(math.degrees(v)) for v in tool_tilt(arm, step.branch)),
            *controller_values(arm, step.q),
            *(repr(float(v)) for v in step.q),
            *(repr(v) for v in _display(step.q, arm.joint_types)),
            repr(step.travel), repr(math.degrees(step.travel)), repr(step.time),
            int(step.collision), repr(math.degrees(move.max_step)), int(move.air_move),
            int(move.reconfiguration), *_margins(move), move.near_singularities,
            *_line(move), repr(1000.0 * gap), " – ".join(pair) if pair[0] else "",
            repr(cumulative), repr(math.degrees(cumulative)),
            *(str(plan.extras[column][step.waypoint]) for column in plan.extras),
        ])
    return buffer.getvalue()


SUMMARY = ("planner", "success", "return", "travel deg", "time s", "collisions",
           "reconfigurations", "gap", "ms/waypoint")


def summary(plan: Plan) -> dict[str, dict[str, Any]]:
    """Per planner: return, travel (rad, deg), time (s), collisions, success, gap to the
    optimum, decision time (ms per waypoint), waypoints reached."""
    out = {}
    for key, run in plan.runs.items():
        moves = plan.moves(run)
        out[key] = {
            "spec": run.spec, "return": run.reward, "travel": run.travel,
            "travel_deg": math.degrees(run.travel), "time": run.time,
            "collisions": run.collisions,
            "reconfigurations": sum(move.reconfiguration for move in moves),
            "near_singularities": sum(bool(move.near_singularities) for move in moves),
            "off_line": sum(move.off_line for move in moves),
            "success": run.success, "gap": plan.gap(run),
            "decision_ms": 1e3 * run.decision_seconds / max(len(run.steps), 1),
            "waypoints_reached": len(run.reached), "n_waypoints": run.n_waypoints,
            "problem": run.problem(),
        }
    return out


def summary_table(plan: Plan) -> str:
    """An aligned text table of every planner beside the optimum."""
    rows = [list(SUMMARY)]
    for key, m in summary(plan).items():
        mark = " (optimum)" if key == ORACLE else ""
        mark += " *" if key == plan.chosen else ""
        gap = "n/a" if m["gap"] is None else f"{m['gap']:.2%}"
        rows.append([key + mark, "yes" if m["success"] else "NO", f"{m['return']:.6f}",
                     f"{m['travel_deg']:.2f}", f"{m['time']:.3f}", str(m["collisions"]),
                     str(m["reconfigurations"]), gap, f"{m['decision_ms']:.3f}"])
    widths = [max(len(row[c]) for row in rows) for c in range(len(SUMMARY))]
    lines = ["  ".join(cell.rjust(w) if c else cell.ljust(w)
                       for c, (cell, w) in enumerate(zip(row, widths, strict=True)))
             for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _sha256(path: Path | None) -> str | None:
    if path is None:
        return None
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def versions(extra: Sequence[str] = ()) -> dict[str, str]:
    found = {"python": platform.python_version()}
    for name in (*VERSIONED, *extra):
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "not installed"
    return found


def _matrix(pose: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in pose]


def plan_json(plan: Plan, argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Everything: the inputs, the waypoints, every planner's steps, the summary."""
    request, arm = plan.request, plan.arm
    scene = None
    if request.scene is not None:
        scene = {
            "path": str(request.scene), "sha256": _sha256(request.scene),
            "options": request.scene_options,
            "base_pose": _matrix(plan.scene.base_pose) if plan.scene is not None else None,
            "meshes": [] if plan.scene is None else [
                {"name": m.name, "convex": m.convex, "parts": m.n_parts, "cached": m.cached}
                for m in plan.scene.meshes],
        }
    models = any(run.spec.endswith(".zip") for run in plan.runs.values())
    waypoints = []
    for i, name in enumerate(plan.names):
        waypoints.append({"index": i, "row": plan.rows[i], "name": name,
                          "source": plan.sources[i],
                          "pose": _matrix(plan.file_poses[i]),
                          "fk_pose": _matrix(plan.targets[i])})
    planners = {}
    for key, run in plan.runs.items():
        steps = []
        moves = iter(plan.moves(run))
        gaps = iter(plan.clearances(run))
        for step in run.steps:
            entry: dict[str, Any] = {
                "waypoint": step.waypoint, "name": plan.names[step.waypoint],
                "branch": step.branch, "label": step.label,
                "q": None if step.invalid else [float(v) for v in step.q],
                "reward": step.reward, **step.terms, "travel": step.travel,
                "time": step.time, "collision": step.collision, "invalid": step.invalid,
                "contacts": [list(pair) for pair in step.contacts],
                "contact_fraction": step.contact_fraction,
            }
            entry["segment"] = int(plan.segments[step.waypoint])
            if not step.invalid:
                fk = arm.fk(step.q)
                target = plan.targets[step.waypoint]
                if hasattr(arm, "branch_pose"):  # a free tool axis: the pose turned
                    target = arm.branch_pose(target, step.branch)
                entry["fk_residual"] = float(np.abs(fk - target).max())
                entry["tool_angle"] = tool_angle(arm, step.branch)
                entry["tool_tilt"], entry["tool_tilt_azimuth"] = tool_tilt(arm, step.branch)
                entry["controller_configuration"] = dict(zip(
                    controller_columns(arm), controller_values(arm, step.q), strict=True))
                gap, pair = next(gaps)
                entry["clearance"], entry["clearance_pair"] = gap, list(pair) if pair[0] else []
                move = next(moves)
                entry.update(configuration=move.configuration, max_step=move.max_step,
                             air_move=move.air_move, reconfiguration=move.reconfiguration,
                             singularity_margins=None if move.margins is None else dict(
                                 zip(("wrist", "elbow", "shoulder"), move.margins,
                                     strict=True)),
                             near_singularity=move.near_singularities,
                             line_deviation=move.line_deviation,
                             line_rotation=move.line_rotation, off_line=move.off_line)
            steps.append(entry)
        planners[key] = {"spec": run.spec, "steps": steps}
    return {
        "format": FORMAT,
        "inputs": {
            "command": None if argv is None else ["ikbranch", "plan", *argv],
            "arm": request.arm, "arm_params": request.arm_params,
            "joint_names": list(arm.joint_names), "joint_types": list(arm.joint_types),
            "joint_limits": [[float(lo), float(hi)] for lo, hi in arm.joint_limits],
            "branch_labels": list(arm.branch_labels),
            "waypoints": {"path": str(request.waypoints), "sha256": _sha256(request.waypoints),
                          "points_abc_mm": None if request.points_abc is None
                          else list(request.points_abc)},
            "scene": scene,
            "tool": None if request.tool is None else {
                "spec": request.tool,
                "path": None if request.tool_file is None else str(request.tool_file),
                "tcp": _matrix(plan.tool.tcp) if plan.tool is not None else None},
            "start": {"free": plan.free_start,
                      "q": None if plan.free_start else [float(v) for v in plan.start]},
            "process": _process_record(plan),
            "allowed_contacts": [list(pair) for pair in plan.allowed_contacts],
            "skipped": list(plan.skipped),
            "joint_speeds": {
                "source": ("rated" if request.joint_speeds == "rated" else "generic"
                           if request.joint_speeds is None else "given"),
                "values": [float(v) for v in np.asarray(plan.joint_speeds)]},
            "planners": list(request.planners),
            "env_kwargs": request.make_kwargs(),
            "versions": versions(("torch", "stable-baselines3", "sb3-contrib") if models
                                 else ()),
        },
        "chosen": plan.chosen,
        "optimum": ORACLE,
        "waypoints": waypoints,
        "summary": summary(plan),
        "planners": planners,
    }


def _process_record(plan: Plan) -> dict[str, Any]:
    """The JSON's ``inputs.process``: the segments and the step limit, how it came about."""
    starts = [0, *(int(w) for w in np.flatnonzero(np.diff(plan.segments)) + 1)]
    kept = plan.continuity
    requested = plan.request.max_joint_step
    return {
        "segment_starts": starts,
        "continuity": kept is not None,
        "max_joint_step_requested": (None if requested is None else requested
                                     if isinstance(requested, str) else float(requested)),
        "max_joint_step": plan.limit, "max_joint_step_deg": math.degrees(plan.limit),
        "derived": None if kept is None else kept.derived,
        "segment_needs": None if kept is None else [float(v) for v in kept.needed],
        "singularity_margin": plan.singularity_margin,
        "singularity_margin_deg": math.degrees(plan.singularity_margin),
        "shoulder_margin": plan.shoulder_margin,
        "singularities_avoided": plan.singularities_avoided,
        "line_tolerance": plan.line_tolerance,
    }
