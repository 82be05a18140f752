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

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import json
import math
import platform
import sys
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbranch_gym.agents import BASELINES
from ikbranch_gym.agents.evaluation import ORACLE, parse_spec
from ikbranch_gym.envs.files import write_all_atomically
from ikbranch_gym.envs.process import MAX_LIMIT, largest_steps, segment_index

if TYPE_CHECKING:
    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
    from ikbranch_gym.envs.kinematics import Arm

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_UNSAFE = 0, 1, 2, 3
#: The planner names ``--planner`` takes besides ``MODEL.zip``: the baselines
#: (``receding_dp:H``, ``fixed:BRANCH``, ``random:SEED`` take an argument).
PLANNERS = tuple(BASELINES)
#: Env arguments ``--env-kwargs`` may not set: they have options of their own (or are
#: fixed by the command).
RESERVED_ENV_KWARGS = ("arm", "arm_params", "scene", "scene_file", "scene_options", "task",
                       "task_file", "task_start", "task_points_abc", "task_segments",
                       "max_joint_step", "tool", "collision_resolution", "n_waypoints",
                       "render_mode", "width", "height")
#: Packages whose versions the JSON records.
VERSIONED = ("ikbranch-gym", "numpy", "mujoco", "gymnasium", "coacd", "numba")
#: The seed of ``reset`` and of ``random`` (a file task draws nothing).
SEED = 0
FORMAT = "ikbranch-plan/2"


class PlanInputError(ValueError):
    """Bad input to ``ikbranch plan``: the message says what and where (exit status 2)."""


# ------------------------------------------------------------------------------ the request
@dataclass(frozen=True)
class PlanRequest:
    """What to plan. Paths as given (relative to the working directory); ``start`` None is
    the free start, else (dof,) rad/m; ``tool`` a tool dict (``envs/tools.py``)."""

    arm: str
    waypoints: Path
    arm_params: dict[str, Any] | None = None
    points_abc: tuple[float, float, float] | None = None
    scene: Path | None = None
    scene_options: dict[str, Any] | None = None
    tool: dict[str, Any] | None = None
    tool_file: Path | None = None
    start: np.ndarray | None = None
    planners: tuple[str, ...] = (ORACLE,)
    resolution: float = 0.01
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    #: Process continuity: the step limit (rad), "auto" (derived) or None (off), and the
    #: first waypoints of the segments (None: the file's own).
    max_joint_step: float | str | None = "auto"
    segments: tuple[int, ...] | None = None

    def make_kwargs(self) -> dict[str, Any]:
        """The :class:`~envs.ik_branch_env.IKBranchEnv` arguments (JSON-able)."""
        kwargs: dict[str, Any] = {
            "arm": self.arm, "arm_params": self.arm_params, "task": "file",
            "task_file": str(self.waypoints),
            "task_start": None if self.start is None else [float(v) for v in self.start],
            "task_points_abc": None if self.points_abc is None else list(self.points_abc),
            "scene": "empty" if self.scene is None else "file",
            "scene_file": None if self.scene is None else str(self.scene),
            "scene_options": self.scene_options, "tool": self.tool,
            "collision_resolution": self.resolution,
            "task_segments": None if self.segments is None else list(self.segments),
            "max_joint_step": self.max_joint_step,
        }
        return {**kwargs, **self.env_kwargs}


def make_env(request: PlanRequest) -> IKBranchEnv:
    """A fresh ``IKBranchEnv`` of the request (``ValueError`` for any bad input it finds)."""
    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv

    return IKBranchEnv(**request.make_kwargs())


# --------------------------------------------------------------------------- playing
@dataclass(frozen=True)
class Step:
    """One step of a plan: the move into ``waypoint`` with ``branch``; ``q`` (dof,) is
    ``env.q`` after it (the configuration moved to), ``terms`` the reward terms."""

    waypoint: int
    branch: int
    label: str
    q: np.ndarray
    reward: float
    terms: dict[str, float]
    travel: float
    time: float
    collision: bool
    invalid: bool
    #: A colliding move: the geom pairs in contact at its first colliding sample (the
    #: exact check's own contacts; at a free start the configuration's), and where along
    #: the move that sample lies (t in [0, 1]; 1.0 at a free start).
    contacts: tuple[tuple[str, str], ...] = ()
    contact_fraction: float | None = None


@dataclass(frozen=True)
class PlanRun:
    """One planner's episode on the task."""

    name: str
    spec: str
    steps: tuple[Step, ...]
    reward: float  # the return: the env's rewards summed in order
    success: bool
    decision_seconds: float  # inside ``predict``, planning included
    n_waypoints: int

    @property
    def travel(self) -> float:
        return sum(s.travel for s in self.steps)

    @property
    def time(self) -> float:
        return sum(s.time for s in self.steps)

    @property
    def collisions(self) -> int:
        return sum(s.collision for s in self.steps)

    @property
    def reached(self) -> tuple[Step, ...]:
        """The steps that moved the arm (every step but an invalid branch's)."""
        return tuple(s for s in self.steps if not s.invalid)

    def problem(self) -> str:
        """Why the plan is not a success ("" if it is)."""
        if self.success:
            return ""
        reasons = []
        for step in self.steps:
            if step.collision:
                where = ("" if step.contact_fraction is None
                         else f" at {step.contact_fraction:.0%} of the move")
                pairs = ", ".join(f"{a} – {b}" for a, b in step.contacts)
                reasons.append(f"the move into waypoint {step.waypoint} collides{where}"
                               + (f" ({pairs})" if pairs else ""))
        bad = [s.waypoint for s in self.steps if s.invalid]
        if bad:
            reasons.append(f"an invalid branch at waypoint {bad[0]}")
        done = len(self.reached)
        if done < self.n_waypoints:
            reasons.append(f"only {done} of {self.n_waypoints} waypoints were reached")
        return "; ".join(reasons) or "the episode did not succeed"


def play(policy: Any, env: Any) -> tuple[tuple[Step, ...], float, bool, float]:
    """One deterministic episode of ``policy`` on ``env`` (as
    ``agents.evaluation.run_episode`` plays it), recorded step by step: (steps, return,
    success, decision seconds)."""
    obs, _ = env.reset(seed=SEED)
    base = env.unwrapped
    labels = base.arm.branch_labels
    state, start, done = None, True, False
    steps, reward, decision, success = [], 0.0, 0.0, False
    while not done:
        masks = base.action_masks()
        tick = time.perf_counter()
        action, state = policy.predict(obs, state=state, episode_start=np.array([start]),
                                       deterministic=True, action_masks=masks)
        decision += time.perf_counter() - tick
        branch = int(np.asarray(action).item())
        before = base.q.copy()
        obs, r, terminated, truncated, info = env.step(branch)
        start, done = False, terminated or truncated
        reward += float(r)
        success = bool(info.get("is_success", False))
        steps.append(Step(
            waypoint=int(info["waypoint"]), branch=branch, label=labels[branch],
            q=base.q.copy(), reward=float(r),
            terms={k: float(v) for k, v in info.items() if k.startswith("reward_")},
            travel=float(info["travel"]), time=float(info["time"]),
            collision=bool(info["collision"]), invalid=bool(info["invalid"]),
            **(_contacts(base, before, int(info["waypoint"])) if info["collision"] else {}),
        ))
    return tuple(steps), reward, success, decision


def _contacts(base: Any, before: np.ndarray, waypoint: int) -> dict[str, Any]:
    """What a colliding move hits: the exact check's contacts at its first colliding
    sample (``Step.contacts``, ``Step.contact_fraction``)."""
    if waypoint == 0 and base.task.free_start:  # the first pick: the configuration itself
        found = base.checker.contacts(base.q)
        return {"contacts": tuple(sorted({(c.geom1, c.geom2) for c in found})),
                "contact_fraction": 1.0}
    result = base.checker.check_path(before, base.q)
    return {"contacts": result.pairs, "contact_fraction": result.first_fraction}


@dataclass(frozen=True)
class ProcessMove:
    """A plan row's process view: its waypoint's ``segment``, the ``configuration`` it
    stands in (the closed-form branch label, turns aside), the move's largest revolute
    joint step (rad; 0 for a free start's first row), whether it is an ``air_move`` (into
    the first waypoint or a new segment) and whether it reconfigures the arm (a new
    configuration, or a step beyond the plan's limit)."""

    segment: int
    configuration: str
    max_step: float
    air_move: bool
    reconfiguration: bool


@dataclass
class Plan:
    """Every planner's run on the task, the oracle's first; ``chosen`` the first
    ``--planner``'s key (the one written to the CSV)."""

    request: PlanRequest
    runs: dict[str, PlanRun]
    chosen: str
    arm: Any
    names: tuple[str, ...]
    sources: tuple[str, ...]  # "line 3" / "entry 2" per waypoint
    file_poses: np.ndarray  # (N, 4, 4) as written in the file (cell frame, TCP)
    targets: np.ndarray  # (N, 4, 4) the fk frame's poses in the base frame
    start: np.ndarray  # where the first move starts (free start: unused)
    free_start: bool
    model: Any  # the MuJoCo model (for the animation)
    segments: np.ndarray  # (N,) each waypoint's process segment
    #: The step limit inside segments (rad): given or derived; with continuity off, half a
    #: revolution (``MAX_LIMIT``: only flips and turn changes are flagged). ``continuity``:
    #: the ladder's ``envs.process.Continuity`` (None: off).
    limit: float
    continuity: Any = None
    scene: Any = None  # the SceneFile, if any
    tool: Any = None  # the Tool, if any

    @property
    def optimum(self) -> PlanRun:
        return self.runs[ORACLE]

    def moves(self, run: PlanRun | None = None) -> list[ProcessMove]:
        """The process view of each row of ``run`` (default the chosen planner's)."""
        run = self.chosen_run if run is None else run
        arm = self.arm
        closed, labels = arm.branch_closed_form, arm.closed_form_labels
        out: list[ProcessMove] = []
        previous: Step | None = None
        for step in run.reached:
            air = step.waypoint == 0 or bool(
                self.segments[step.waypoint] != self.segments[step.waypoint - 1])
            if previous is None and self.free_start:  # the arm stands there already
                largest, changed = 0.0, False
            else:
                before = self.start if previous is None else previous.q
                largest = float(largest_steps(before, step.q, arm.revolute_mask))
                changed = largest > self.limit or (
                    previous is not None and closed[previous.branch] != closed[step.branch])
            out.append(ProcessMove(int(self.segments[step.waypoint]),
                                   labels[closed[step.branch]], largest, bool(air),
                                   bool(changed)))
            previous = step
        return out

    @property
    def chosen_run(self) -> PlanRun:
        return self.runs[self.chosen]

    def gap(self, run: PlanRun) -> float | None:
        """(optimum − return) / |optimum| as ``agents.evaluation.summarise`` measures it."""
        best = self.optimum.reward
        if best != 0.0:
            return (best - run.reward) / abs(best)
        return 0.0 if run.reward == best else None


def plan(request: PlanRequest) -> Plan:
    """Play every planner of ``request`` (and the oracle) on its task, each in its own
    fresh env, so no planner inherits another's collision cache and its decision time is
    its own. Every planner first plays once untimed on a throwaway env: numba compiles its
    kernels on first use (or loads them from its cache), torch warms up, and a first run
    after an install would otherwise report that as decision time. ``ValueError`` (a bad
    file, an unreachable row, an unknown planner, a model that does not fit the env, …)
    is bad input."""
    from ikbranch_gym.agents.evaluation import build_policy
    from ikbranch_gym.envs.tasks.waypoint_file import read_waypoints

    first: Any = make_env(request)  # fails early on bad input, before any planner is built
    specs = [ORACLE, *(spec for spec in request.planners if spec != ORACLE)]
    opened = [first]
    runs: dict[str, PlanRun] = {}
    try:
        for spec in dict.fromkeys(specs):  # untimed warm-up plays
            play(build_policy(spec, first, SEED)[1], first)
        for spec in specs:
            env: Any = make_env(request)
            opened.append(env)
            _, policy = build_policy(spec, env, SEED)
            key, copy = spec, 2
            while key in runs:  # the same spec twice: its own row
                key, copy = f"{spec}#{copy}", copy + 1
            steps, reward, success, decision = play(policy, env)
            runs[key] = PlanRun(key, spec, steps, reward, success, decision,
                                env.unwrapped.task.n_waypoints)
    finally:
        for env in opened:
            env.close()
    base = first.unwrapped
    a, b, c = request.points_abc or (None, None, None)
    waypoints = read_waypoints(request.waypoints, a=a, b=b, c=c)
    task = base.task
    kept = base.ladder.continuity
    segments = (waypoints.segments if request.segments is None
                else segment_index(len(waypoints), request.segments))
    return Plan(
        request=request, runs=runs, chosen=request.planners[0], arm=base.arm,
        names=waypoints.names,
        sources=tuple(waypoints.where(i) for i in range(len(waypoints))),
        file_poses=np.array(waypoints.poses), targets=np.array(task.poses),
        start=np.array(task.start), free_start=bool(task.free_start), model=base.model,
        segments=segments, limit=MAX_LIMIT if kept is None else kept.limit, continuity=kept,
        scene=base.scene_file, tool=base.tool,
    )


# --------------------------------------------------------------------------- outputs
def _unit_suffix(kind: str) -> str:
    return "mm" if kind == "prismatic" else "deg"


def _display(values: np.ndarray, kinds: Sequence[str]) -> list[float]:
    """Joint values in the degree column set: revolute in degrees, prismatic in mm."""
    return [float(np.degrees(v)) if kind != "prismatic" else float(v * 1000.0)
            for v, kind in zip(values, kinds, strict=True)]


def csv_columns(arm: Arm) -> list[str]:
    names, kinds = arm.joint_names, arm.joint_types
    return (["waypoint", "name", "segment", "branch", "label", "configuration", *names,
             *(f"{n}_{_unit_suffix(k)}" for n, k in zip(names, kinds, strict=True)),
             "travel_rad", "travel_deg", "time_s", "collision", "max_step_deg", "air_move",
             "reconfiguration", "cumulative_travel_rad", "cumulative_travel_deg"])


def plan_csv(plan: Plan, run: PlanRun | None = None) -> str:
    """The plan of ``run`` (default the chosen planner's) as CSV text: one row per
    waypoint reached, every float as its shortest round-trip ``repr``."""
    run = plan.chosen_run if run is None else run
    arm = plan.arm
    buffer = io.StringIO(newline="")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(csv_columns(arm))
    cumulative = 0.0
    for step, move in zip(run.reached, plan.moves(run), strict=True):
        cumulative += step.travel
        writer.writerow([
            step.waypoint, plan.names[step.waypoint], move.segment, step.branch, step.label,
            move.configuration, *(repr(float(v)) for v in step.q),
            *(repr(v) for v in _display(step.q, arm.joint_types)),
            repr(step.travel), repr(math.degrees(step.travel)), repr(step.time),
            int(step.collision), repr(math.degrees(move.max_step)), int(move.air_move),
            int(move.reconfiguration), repr(cumulative), repr(math.degrees(cumulative)),
        ])
    return buffer.getvalue()


SUMMARY = ("planner", "success", "return", "travel deg", "time s", "collisions",
           "reconfigurations", "gap", "ms/waypoint")


def summary(plan: Plan) -> dict[str, dict[str, Any]]:
    """Per planner: return, travel (rad, deg), time (s), collisions, success, gap to the
    optimum, decision time (ms per waypoint), waypoints reached."""
    out = {}
    for key, run in plan.runs.items():
        out[key] = {
            "spec": run.spec, "return": run.reward, "travel": run.travel,
            "travel_deg": math.degrees(run.travel), "time": run.time,
            "collisions": run.collisions,
            "reconfigurations": sum(move.reconfiguration for move in plan.moves(run)),
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
        waypoints.append({"index": i, "name": name, "source": plan.sources[i],
                          "pose": _matrix(plan.file_poses[i]),
                          "fk_pose": _matrix(plan.targets[i])})
    planners = {}
    for key, run in plan.runs.items():
        steps = []
        moves = iter(plan.moves(run))
        for step in run.steps:
            entry = {
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
                entry["fk_residual"] = float(np.abs(fk - plan.targets[step.waypoint]).max())
                move = next(moves)
                entry.update(configuration=move.configuration, max_step=move.max_step,
                             air_move=move.air_move, reconfiguration=move.reconfiguration)
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
    }


# ------------------------------------------------------------------------------- the GIF
@dataclass(frozen=True)
class Frame:
    """One animation frame: the configuration, its caption and how long it shows (s)."""

    q: np.ndarray
    lines: tuple[str, ...]
    duration: float
    alert: bool = False


def animation_frames(plan: Plan, run: PlanRun | None = None, fps: float = 12.0,
                     speed: float = 1.0, hold: float = 0.5) -> list[Frame]:
    """The plan as frames: each joint-space move interpolated linearly (the path the env
    checks) in real time at the env's joint speeds (``speed`` times faster: a move of
    ``time`` s gets ``ceil(time · fps / speed)`` frames), and each waypoint held ``hold``
    s. Captions say the waypoint, the branch label and the travel so far (interpolated
    along each move); a colliding move's frames say so, in red."""
    run = plan.chosen_run if run is None else run
    steps = run.reached
    n = run.n_waypoints
    frames: list[Frame] = []

    def frame(q: np.ndarray, step: Step, travel: float, moving: bool,
              duration: float) -> Frame:
        # The CSV's 0-based waypoint index (of 0 … n − 1), then the file's name for it.
        where = f"{'to ' if moving else ''}waypoint {step.waypoint} of 0–{n - 1}"
        return Frame(
            q=np.asarray(q), duration=duration,
            lines=(f"{where}: {plan.names[step.waypoint]}",
                   f"branch {step.branch}: {step.label}",
                   f"travel {math.degrees(travel):.1f} deg   [{run.name}]"
                   + ("   COLLISION" if step.collision else "")),
            alert=step.collision)

    if not steps:
        return frames
    travelled, tick = 0.0, 1.0 / fps
    if plan.free_start or steps[0].waypoint != 0:
        previous = steps[0].q
    else:
        previous = plan.start
        frames.append(Frame(q=previous, lines=("start", "", f"travel 0.0 deg   [{run.name}]"),
                            duration=hold))
    for step in steps:
        count = 1
        if not np.array_equal(previous, step.q):
            count = max(1, math.ceil(step.time * fps / speed))
            for k in range(1, count):
                t = k / count
                frames.append(frame(previous + t * (step.q - previous), step,
                                    travelled + t * step.travel, True, tick))
        travelled += step.travel
        frames.append(frame(step.q, step, travelled, False, hold + (tick if count > 1 else 0)))
        previous = step.q
    return frames


def _font(size: int) -> Any:
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError, ImportError):  # Pillow without FreeType: the bitmap font
        return ImageFont.load_default()


def annotate(rgb: np.ndarray, lines: Sequence[str], alert: bool = False) -> np.ndarray:
    """``rgb`` with ``lines`` written on a dark band at its top (red text if ``alert``)."""
    from PIL import Image, ImageDraw

    image = Image.fromarray(rgb)
    draw = ImageDraw.Draw(image, "RGBA")
    size = max(10, rgb.shape[0] // 26)
    font = _font(size)
    band = 6 + len(lines) * (size + 4)
    draw.rectangle((0, 0, rgb.shape[1], band), fill=(0, 0, 0, 160))
    colour = (255, 90, 80) if alert else (255, 255, 255)
    for i, line in enumerate(lines):
        draw.text((6, 4 + i * (size + 4)), line, fill=colour, font=font)
    return np.asarray(image)


def render_frames(plan: Plan, frames: Sequence[Frame], width: int = 480,
                  height: int = 360) -> list[np.ndarray]:
    """Rendered, annotated RGB frames; the camera frames the arm over every pose it sweeps
    (its own geoms and the tool, not the whole cell)."""
    from ikbranch_gym.envs.render import SceneRenderer, arm_geoms

    samples = [frame.q for frame in frames]
    with SceneRenderer(plan.model, width=width, height=height, frame_qs=samples,
                       frame_geoms=arm_geoms(plan.model)) as renderer:
        return [annotate(renderer.render(frame.q), frame.lines, frame.alert)
                for frame in frames]


def gif_bytes(images: Sequence[np.ndarray], durations: Sequence[float]) -> bytes:
    """An endlessly looping GIF; ``durations`` in seconds, one per image."""
    import imageio.v3 as iio

    return iio.imwrite("<bytes>", np.stack(images), extension=".gif",
                       duration=[round(1000.0 * d) for d in durations], loop=0)


# ------------------------------------------------------------------------ parsing inputs
def _json_value(text: str, option: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise PlanInputError(f"{option}: not valid JSON ({exc.msg} at line {exc.lineno} "
                             f"column {exc.colno}): {text!r}") from None


def _json_object(text: str | None, option: str) -> dict[str, Any] | None:
    if text is None:
        return None
    value = _json_value(text, option)
    if not isinstance(value, dict):
        raise PlanInputError(f"{option} must be a JSON object, got {text!r}")
    return value


def _solids(spec: dict) -> list[dict]:
    """The solids of a tool spec: its parts, or the spec itself (``envs/tools.py``)."""
    parts = spec.get("parts")
    if isinstance(parts, list):
        return [part for part in parts if isinstance(part, dict)]
    return [spec]


def _check_mesh(spec: dict, option: str) -> None:
    for solid in _solids(spec):
        if "mesh" in solid and not isinstance(solid["mesh"], str):
            raise PlanInputError(f"{option}: mesh must be the path of an STL/OBJ file (a "
                                 f"string), got {solid['mesh']!r}")


def parse_tool(text: str | None) -> tuple[dict[str, Any] | None, Path | None]:
    """``--tool``: JSON text (starting with ``{``) or the path of a JSON file; a relative
    ``mesh`` in a file is relative to that file's folder."""
    if text is None:
        return None, None
    if text.lstrip().startswith("{"):
        spec = _json_object(text, "--tool")
        assert spec is not None  # the text is not None
        _check_mesh(spec, "--tool")
        return spec, None
    path = Path(text)
    if not path.is_file():
        raise PlanInputError(f"--tool {text}: no such file (give a tool as JSON text "
                             "starting with '{' or the path of a JSON file)")
    try:
        content = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise PlanInputError(f"--tool {text}: cannot read it ({exc})") from None
    try:
        spec = json.loads(content)
    except json.JSONDecodeError as exc:
        raise PlanInputError(f"--tool {text}: line {exc.lineno} column {exc.colno}: not "
                             f"valid JSON ({exc.msg})") from None
    if not isinstance(spec, dict):
        raise PlanInputError(f"--tool {text}: must hold a JSON object")
    _check_mesh(spec, f"--tool {text}")
    for solid in _solids(spec):  # the one solid, or every part
        if isinstance(solid.get("mesh"), str) and not Path(solid["mesh"]).is_absolute():
            solid["mesh"] = str(path.parent / solid["mesh"])
    return spec, path


def parse_start(text: str, degrees: bool, arm: Arm) -> np.ndarray | None:
    """``--start``: ``free`` (None), ``home`` or comma-separated joint values (rad and m;
    with ``degrees``, deg and mm), checked against the limits (never wrapped)."""
    word = text.strip().lower()
    if word in ("free", "home"):
        if degrees:
            raise PlanInputError(f"--start-degrees needs joint values, not --start {word}")
        return None if word == "free" else np.array(arm.home, dtype=np.float64)
    parts = [part.strip() for part in text.split(",")]
    values = []
    for part in parts:
        try:
            value = float(part)
        except ValueError:
            raise PlanInputError(
                f"--start {text!r}: {part!r} is not a number (give 'free', 'home' or "
                f"{arm.dof} comma-separated joint values)") from None
        if not math.isfinite(value):
            raise PlanInputError(f"--start {text!r}: {part!r} is not a finite number")
        values.append(value)
    if len(values) != arm.dof:
        raise PlanInputError(f"--start {text!r}: {arm.name} has {arm.dof} joints "
                             f"({', '.join(arm.joint_names)}), got {len(values)} values")
    q = np.array(values, dtype=np.float64)
    if degrees:
        q = np.array([math.radians(v) if kind != "prismatic" else v / 1000.0
                      for v, kind in zip(values, arm.joint_types, strict=True)])
    from ikbranch_gym.envs.kinematics.arm import LIMIT_TOL

    outside = []
    for name, kind, value, (lower, upper) in zip(arm.joint_names, arm.joint_types, q,
                                                 arm.joint_limits, strict=True):
        value = float(value)
        if not lower - LIMIT_TOL <= value <= upper + LIMIT_TOL:
            if kind == "prismatic":
                outside.append(f"{name} = {value!r} m outside [{lower:g}, {upper:g}] m")
            else:
                outside.append(f"{name} = {value!r} rad ({math.degrees(value):.2f}°) outside "
                               f"[{lower:.4f}, {upper:.4f}] rad ([{math.degrees(lower):.1f}, "
                               f"{math.degrees(upper):.1f}]°)")
    if outside:
        raise PlanInputError(f"--start lies outside {arm.name}'s joint limits (values are "
                             "never wrapped): " + "; ".join(outside))
    return q


def parse_max_joint_step(text: str) -> float | str | None:
    """``--max-joint-step``: degrees (0 < value ≤ 179), ``auto`` or ``off``; radians out."""
    word = text.strip().lower()
    if word in ("auto", "off"):
        return None if word == "off" else "auto"
    try:
        degrees = float(word)
    except ValueError:
        raise PlanInputError(f"--max-joint-step {text!r}: give degrees, 'auto' (derived from "
                             "the job) or 'off'") from None
    if not (math.isfinite(degrees) and 0.0 < degrees <= math.degrees(MAX_LIMIT)):
        raise PlanInputError(f"--max-joint-step {text!r}: must lie in (0, "
                             f"{math.degrees(MAX_LIMIT):g}] degrees (a step of half a "
                             "revolution or more is a turn change)")
    return math.radians(degrees)


def parse_segments(text: str | None) -> tuple[int, ...] | None:
    """``--segments``: the 0-based waypoints where segments begin, comma-separated."""
    if text is None:
        return None
    starts = []
    for part in text.split(","):
        try:
            starts.append(int(part.strip()))
        except ValueError:
            raise PlanInputError(f"--segments {text!r}: {part.strip()!r} is not a waypoint "
                                 "index (give the 0-based waypoints where segments begin, "
                                 "e.g. 0,12,40)") from None
    return tuple(starts)


def _scene_options(options: dict[str, Any] | None, scene: Path | None) -> dict | None:
    if options is None:
        return None
    if scene is None:
        raise PlanInputError("--scene-options need --scene (a scene file)")
    from ikbranch_gym.envs.ik_branch_env import SCENE_OPTIONS

    unknown = sorted(set(options) - set(SCENE_OPTIONS["file"]))
    if unknown:
        raise PlanInputError(f"--scene-options: unknown keys {unknown}; known: "
                             f"{', '.join(SCENE_OPTIONS['file'])}")
    for key in ("base_pos", "base_quat", "base_rpy"):
        value = options.get(key)
        if value is not None and not (isinstance(value, list) and all(
                isinstance(v, int | float) and not isinstance(v, bool) for v in value)):
            raise PlanInputError(f"--scene-options: {key} must be a list of numbers, got "
                                 f"{value!r}")
    if "floor" in options and not isinstance(options["floor"], bool):
        raise PlanInputError(f"--scene-options: floor must be true or false, got "
                             f"{options['floor']!r}")
    if "decompose" in options and not isinstance(options["decompose"], str):
        raise PlanInputError(f"--scene-options: decompose must be a string, got "
                             f"{options['decompose']!r}")
    if "coacd_options" in options and not isinstance(options["coacd_options"], dict):
        raise PlanInputError(f"--scene-options: coacd_options must be an object, got "
                             f"{options['coacd_options']!r}")
    return options


def _planner(spec: str) -> str:
    if spec.endswith(".zip"):
        if not Path(spec).is_file():
            raise PlanInputError(f"--planner {spec}: no such model file")
        return spec
    try:
        parse_spec(spec)
    except ValueError as exc:
        raise PlanInputError(f"--planner {spec!r}: {exc} (or give a model .zip)") from None
    return spec


def request_from_args(args: argparse.Namespace) -> PlanRequest:
    """Check the command line (``PlanInputError`` naming the option) into a request."""
    from ikbranch_gym.envs.kinematics import make_arm

    arm_params = _json_object(args.arm_params, "--arm-params")
    try:
        arm = make_arm(args.arm, **(arm_params or {}))
    except ValueError as exc:
        raise PlanInputError(f"--arm: {exc}") from None
    if arm.target != "pose":  # before the file is read: its rows would all look out of reach
        raise PlanInputError(f"--arm {args.arm}: waypoint files give poses; {arm.name} is "
                             f"position-only")
    waypoints = Path(args.waypoints)
    scene = None if args.scene is None else Path(args.scene)
    scene_options = _scene_options(_json_object(args.scene_options, "--scene-options"), scene)
    tool, tool_file = parse_tool(args.tool)
    if tool is not None:
        from ikbranch_gym.envs.tools import Tool

        try:
            Tool.from_spec(tool)
        except (ValueError, TypeError) as exc:  # TypeError: e.g. a number for a mesh path
            raise PlanInputError(f"--tool{' ' + str(tool_file) if tool_file else ''}: "
                                 f"{exc}") from None
    start = parse_start(args.start, args.start_degrees, arm)
    planners = tuple(_planner(spec) for spec in (args.planners or [ORACLE]))
    if not (math.isfinite(args.resolution) and args.resolution > 0):
        raise PlanInputError(f"--resolution must be a positive length in metres, got "
                             f"{args.resolution!r}")
    env_kwargs = _json_object(args.env_kwargs, "--env-kwargs") or {}
    import inspect

    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv

    known = set(inspect.signature(IKBranchEnv.__init__).parameters) - {"self"}
    unknown = sorted(set(env_kwargs) - known)
    if unknown:
        raise PlanInputError(f"--env-kwargs: unknown arguments {unknown}; IKBranchEnv takes "
                             f"{', '.join(sorted(known - set(RESERVED_ENV_KWARGS)))}")
    reserved = sorted(set(env_kwargs) & set(RESERVED_ENV_KWARGS))
    if reserved:
        raise PlanInputError(f"--env-kwargs may not set {', '.join(reserved)}: the command "
                             "sets them from --arm, --arm-params, --waypoints, --points-abc, "
                             "--scene, --scene-options, --tool, --start and --resolution")
    if args.points_abc is not None and any(not math.isfinite(v) for v in args.points_abc):
        raise PlanInputError(f"--points-abc must be finite lengths in mm, got {args.points_abc}")
    return PlanRequest(
        max_joint_step=parse_max_joint_step(args.max_joint_step),
        segments=parse_segments(args.segments),
        arm=args.arm, waypoints=waypoints, arm_params=arm_params,
        points_abc=None if args.points_abc is None else tuple(args.points_abc),
        scene=scene, scene_options=scene_options, tool=tool, tool_file=tool_file,
        start=start, planners=planners, resolution=float(args.resolution),
        env_kwargs=env_kwargs,
    )


def output_paths(args: argparse.Namespace, request: PlanRequest) -> dict[str, Path]:
    """``--out``, ``--json``, ``--gif`` checked: the right suffix, an existing folder,
    distinct from each other and from every input file."""
    outputs = {"--out": Path(args.out)}
    if args.json:
        outputs["--json"] = Path(args.json)
    if args.gif:
        outputs["--gif"] = Path(args.gif)
    suffixes = {"--out": ".csv", "--json": ".json", "--gif": ".gif"}
    for option, path in outputs.items():
        if path.suffix.lower() != suffixes[option]:
            raise PlanInputError(f"{option} {path}: the file name must end in "
                                 f"{suffixes[option]}")
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise PlanInputError(f"{option} {path}: folder {folder} does not exist")
        if path.is_dir():
            raise PlanInputError(f"{option} {path}: is a folder")
    resolved = [path.resolve() for path in outputs.values()]
    if len(set(resolved)) != len(resolved):
        raise PlanInputError("--out, --json and --gif must name different files")
    inputs = [p for p in (request.waypoints, request.scene, request.tool_file) if p]
    for option, path in outputs.items():
        if any(path.resolve() == p.resolve() for p in inputs):
            raise PlanInputError(f"{option} {path} would overwrite an input file")
    return outputs


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="ikbranch plan", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--arm", required=True, help="an arm name (envs.kinematics.ARM_NAMES)")
    p.add_argument("--arm-params", metavar="JSON", help="arm parameters (make_arm), a JSON object")
    p.add_argument("--waypoints", required=True, metavar="FILE",
                   help="waypoint file, CSV or JSON (docs/files.md)")
    p.add_argument("--points-abc", type=float, nargs=3, metavar=("A", "B", "C"),
                   help="four-point files: a, b, c in mm (when the file has no a,b,c columns)")
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
    p.add_argument("--resolution", type=float, default=0.01, metavar="M",
                   help="collision-check clearance and step along paths (m, default 0.01)")
    p.add_argument("--env-kwargs", metavar="JSON",
                   help="further IKBranchEnv arguments, e.g. {\"time_weight\": 1, "
                        "\"lookahead\": 2, \"observation\": \"ladder\"} (for a model)")
    p.add_argument("--out", required=True, metavar="plan.csv", help="the plan (CSV)")
    p.add_argument("--json", metavar="FILE", help="everything, as JSON")
    p.add_argument("--gif", metavar="FILE", help="an animation of the plan")
    p.add_argument("--gif-size", type=int, nargs=2, default=(480, 360),
                   metavar=("W", "H"), help="GIF frame size in pixels (480 360)")
    p.add_argument("--gif-fps", type=float, default=12.0,
                   help="GIF frames per second along a move (12)")
    p.add_argument("--gif-speed", type=float, default=1.0,
                   help="GIF playback speed: 1 is real time at the env's joint speeds (1)")
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


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser().parse_args(_join_negative_start(argv))
    try:
        width, height = args.gif_size
        if width < 16 or height < 16:
            raise PlanInputError(f"--gif-size must be at least 16 16, got {width} {height}")
        for option, value in (("--gif-fps", args.gif_fps), ("--gif-speed", args.gif_speed)):
            if not (math.isfinite(value) and value > 0):
                raise PlanInputError(f"{option} must be a positive number, got {value!r}")
        request = request_from_args(args)
        outputs = output_paths(args, request)
        result = plan(request)
        files = {outputs["--out"]: plan_csv(result).encode("utf-8")}
        if "--json" in outputs:
            record = plan_json(result, argv)
            files[outputs["--json"]] = (json.dumps(record, indent=1, allow_nan=False)
                                        + "\n").encode("utf-8")
        if "--gif" in outputs:
            frames = animation_frames(result, fps=args.gif_fps, speed=args.gif_speed)
            images = render_frames(result, frames, width, height)
            files[outputs["--gif"]] = gif_bytes(images, [f.duration for f in frames])
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
    if not chosen.success:
        optimum = result.optimum
        note = "" if optimum.success else (
            f"; even {ORACLE} finds no collision-free plan ({optimum.problem()})")
        print(f"ikbranch plan: warning: the plan of {chosen.name} is not safe to run: "
              f"{chosen.problem()}{note}", file=sys.stderr)
        return EXIT_UNSAFE
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
