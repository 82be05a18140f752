"""Playing the planners: each in its own fresh env, recorded step by step, into a
:class:`Plan` (every planner's run beside the optimum, and the process view of each row)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbranch_gym.agents.evaluation import ORACLE, run_episode
from ikbranch_gym.envs.kinematics.singularities import has_singularity_rules, singularity_margins
from ikbranch_gym.envs.process import (
    MAX_LIMIT,
    LinearPath,
    largest_steps,
    line_deviation,
    linear_path,
)

from .request import PlanRequest, make_env

if TYPE_CHECKING:
    pass

#: Clearances are measured up to this distance (m); farther is reported as this.
CLEARANCE_RANGE = 1.0
#: The seed of ``reset`` and of ``random`` (a file task draws nothing).
SEED = 0


# --------------------------------------------------------------------------- playing
@dataclass(frozen=True)
class LinearMove:
    """A process move checked as the controller's linear move (``--lin``): the IK samples
    along the line (``envs.process.linear_path``), whether the joint moves between them
    collide (the env's exact path check), and how far those joint moves' TCP leaves the
    line (m) and its slerp (rad): the checked path's distance from the controller's."""

    path: LinearPath
    collision: bool
    deviation: float
    rotation: float

    @property
    def problem(self) -> str | None:
        """Why the move cannot run as a LIN (None: it can)."""
        if self.path.problem is not None:
            return self.path.problem
        return "the line collides" if self.collision else None


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


def _ranges(values: list[int]) -> str:
    """Sorted integers as runs: [1, 2, 3, 7, 9, 10] -> "1–3, 7, 9–10"."""
    runs: list[list[int]] = []
    for value in sorted(values):
        if runs and value == runs[-1][1] + 1:
            runs[-1][1] = value
        else:
            runs.append([value, value])
    return ", ".join(f"{a}–{b}" if b > a else f"{a}" for a, b in runs)


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
        hits = [step for step in self.steps if step.collision]
        if len(hits) == 1:
            step = hits[0]
            where = ("" if step.contact_fraction is None
                     else f" at {step.contact_fraction:.0%} of the move")
            pairs = ", ".join(f"{a} – {b}" for a, b in step.contacts)
            reasons.append(f"the move into waypoint {step.waypoint} collides{where}"
                           + (f" ({pairs})" if pairs else ""))
        elif hits:  # (with terminate_on_collision off) as runs of waypoints
            hit_pairs = sorted({f"{a} – {b}" for step in hits for a, b in step.contacts})
            reasons.append(f"the moves into waypoints {_ranges([s.waypoint for s in hits])} "
                           f"collide" + (f" ({', '.join(hit_pairs)})" if hit_pairs else ""))
        bad = [s.waypoint for s in self.steps if s.invalid]
        if bad:
            reasons.append(f"an invalid branch at waypoint {bad[0]}")
        done = len(self.reached)
        if done < self.n_waypoints:
            reasons.append(f"only {done} of {self.n_waypoints} waypoints were reached")
        return "; ".join(reasons) or "the episode did not succeed"


def play(policy: Any, env: Any) -> tuple[tuple[Step, ...], float, bool, float]:
    """One deterministic episode of ``policy`` on ``env``, played by
    ``agents.evaluation.run_episode`` and recorded step by step: (steps, return, success,
    decision seconds)."""
    base = env.unwrapped
    labels = base.arm.branch_labels
    steps: list[Step] = []

    def record(branch: int, reward: float, info: dict[str, Any]) -> None:
        before = steps[-1].q if steps else base.task.start  # where the move began
        steps.append(Step(
            waypoint=int(info["waypoint"]), branch=branch, label=labels[branch],
            q=base.q.copy(), reward=reward,
            terms={k: float(v) for k, v in info.items() if k.startswith("reward_")},
            travel=float(info["travel"]), time=float(info["time"]),
            collision=bool(info["collision"]), invalid=bool(info["invalid"]),
            **(_contacts(base, before, int(info["waypoint"])) if info["collision"] else {}),
        ))

    episode = run_episode(policy, env, SEED, observe=record)
    return tuple(steps), episode.reward, episode.success, episode.decision_seconds


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
    configuration, or a step beyond the plan's limit); for arms with singularity rules the
    configuration's ``margins`` (wrist, elbow: rad; shoulder: m;
    ``envs.kinematics.singularities``) and ``near_singularities``, the names of those
    within the plan's margins ("" for none); for a move inside a segment, how far the TCP
    leaves the straight line between its ends (``line_deviation``, m) and the orientation
    a linear move would have (``line_rotation``, rad; ``envs.process.line_deviation``),
    and whether it leaves it by more than the plan's tolerance (``off_line``)."""

    segment: int
    configuration: str
    max_step: float
    air_move: bool
    reconfiguration: bool
    margins: tuple[float, float, float] | None = None
    near_singularities: str = ""
    line_deviation: float | None = None
    line_rotation: float | None = None
    off_line: bool = False


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
    extras: dict[str, tuple]  # the passed-through columns' raw values per waypoint
    rows: tuple[int, ...]  # per waypoint its 0-based data row in the file
    skipped: tuple[str, ...]  # the rows left out (--skip-unreachable): why, with where
    file_poses: np.ndarray  # (N, 4, 4) as written in the file (cell frame, TCP)
    targets: np.ndarray  # (N, 4, 4) the fk frame's poses in the base frame
    start: np.ndarray  # where the first move starts (free start: unused)
    free_start: bool
    model: Any  # the MuJoCo model (for the animation)
    segments: np.ndarray  # (N,) each waypoint's process segment
    #: (N, K) the branches every planner chose from (the env's ladder) and those whose
    #: configuration collides.
    ladder_valid: np.ndarray
    ladder_endpoint: np.ndarray
    #: The step limit inside segments (rad): given or derived; with continuity off, half a
    #: revolution (``MAX_LIMIT``: only flips and turn changes are flagged). ``continuity``:
    #: the ladder's ``envs.process.Continuity`` (None: off).
    limit: float
    continuity: Any = None
    #: The margins rows are flagged within (rad: wrist and elbow; m: shoulder), and whether
    #: the planners were kept outside them (``--avoid-singularities``).
    singularity_margin: float = 0.0
    shoulder_margin: float = 0.0
    singularities_avoided: bool = False
    #: A move inside a segment whose TCP leaves the line by more than this (m) is flagged.
    line_tolerance: float = 0.001
    scene: Any = None  # the SceneFile, if any
    tool: Any = None  # the Tool, if any
    #: The geom-name pairs left out of the collision checks (``--allow-contact``).
    allowed_contacts: tuple[tuple[str, str], ...] = ()
    #: (dof,) the joint speeds every move is timed at (rad/s, m/s).
    joint_speeds: np.ndarray | None = None
    #: ``moves`` and ``clearances`` per run name: each output asks for them again.
    _derived: dict[tuple[str, str], Any] = field(default_factory=dict, repr=False)

    def clearances(self, run: PlanRun | None = None) -> list[tuple[float, tuple[str, str]]]:
        """Per row of ``run`` (default the chosen planner's): the least distance (m, at
        most ``CLEARANCE_RANGE``) between any two geoms still checked, at the row's
        configuration, and their names (``envs.models.contacts.clearance``)."""
        import mujoco

        from ikbranch_gym.envs.models.collision import candidate_pairs
        from ikbranch_gym.envs.models.contacts import clearance

        run = self.chosen_run if run is None else run
        key = ("clearances", run.name)
        if key not in self._derived:
            pairs = candidate_pairs(self.model)
            data = mujoco.MjData(self.model)
            self._derived[key] = [clearance(self.model, data, step.q, pairs, CLEARANCE_RANGE)
                                  for step in run.reached]
        return list(self._derived[key])

    def linear_moves(self, run: PlanRun | None = None) -> list[LinearMove | None]:
        """Per row of ``run`` (default the chosen planner's): the move as a linear move,
        checked; None for the first move and air moves (joint moves)."""
        from ikbranch_gym.envs.models.collision import CollisionChecker

        run = self.chosen_run if run is None else run
        key = ("linear", run.name)
        if key not in self._derived:
            kinematic = getattr(self.arm, "base_arm", self.arm)
            checker = CollisionChecker(self.model, dof=kinematic.dof,
                                       resolution=self.request.resolution)
            tcp = None if self.tool is None else self.tool.tcp
            closed = self.arm.branch_closed_form
            found: list[LinearMove | None] = []
            previous: Step | None = None
            for step, move in zip(run.reached, self.moves(run), strict=True):
                if previous is None or move.air_move:
                    found.append(None)
                else:
                    path = linear_path(kinematic, previous.q, step.q,
                                       int(closed[previous.branch]), self.limit, tcp)
                    collision, deviation, rotation = False, 0.0, 0.0
                    if path.problem is None:
                        collision = bool(checker.paths_collide(path.samples[:-1],
                                                               path.samples[1:]).any())
                        for a, b in zip(path.samples[:-1], path.samples[1:], strict=True):
                            off, turn = line_deviation(kinematic.fk, a, b,
                                                       kinematic.revolute_mask, tcp)
                            deviation, rotation = max(deviation, off), max(rotation, turn)
                    found.append(LinearMove(path, collision, deviation, rotation))
                previous = step
            self._derived[key] = found
        return list(self._derived[key])

    @property
    def optimum(self) -> PlanRun:
        return self.runs[ORACLE]

    def moves(self, run: PlanRun | None = None) -> list[ProcessMove]:
        """The process view of each row of ``run`` (default the chosen planner's)."""
        run = self.chosen_run if run is None else run
        key = ("moves", run.name)
        if key not in self._derived:
            self._derived[key] = self._moves(run)
        return list(self._derived[key])

    def _moves(self, run: PlanRun) -> list[ProcessMove]:
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
            margins, near = None, ""
            if has_singularity_rules(arm):
                found = singularity_margins(arm, step.q)
                margins = (float(found.wrist), float(found.elbow), float(found.shoulder))
                near = "+".join(name for name, value, bound in zip(
                    ("wrist", "elbow", "shoulder"), margins,
                    (self.singularity_margin, self.singularity_margin, self.shoulder_margin),
                    strict=True) if value < bound)
            deviation = rotation = None
            if not air and previous is not None:
                deviation, rotation = line_deviation(
                    arm.fk, previous.q, step.q, arm.revolute_mask,
                    None if self.tool is None else self.tool.tcp)
            out.append(ProcessMove(int(self.segments[step.waypoint]),
                                   labels[closed[step.branch]], largest, bool(air),
                                   bool(changed), margins, near, deviation, rotation,
                                   deviation is not None and deviation > self.line_tolerance))
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
    waypoints = read_waypoints(request.waypoints, a=a, b=b, c=c, units=request.units,
                               extra_columns=request.extra_columns)
    task = base.task
    kept = base.ladder.continuity
    rows = [int(row) for row in base._generator.rows]  # the file's rows planned
    return Plan(
        request=request, runs=runs, chosen=request.planners[0], arm=base.arm,
        names=tuple(waypoints.names[row] for row in rows),
        extras={column: tuple(values[row] for row in rows)
                for column, values in waypoints.extras.items()},
        sources=tuple(waypoints.where(row) for row in rows), rows=tuple(rows),
        skipped=tuple(base.skipped_rows),
        file_poses=np.array(waypoints.poses)[rows], targets=np.array(task.poses),
        start=np.array(task.start), free_start=bool(task.free_start), model=base.model,
        segments=np.array(task.segments), ladder_valid=np.array(base.ladder.valid),
        ladder_endpoint=np.array(base.ladder.endpoint_collision),
        limit=MAX_LIMIT if kept is None else kept.limit, continuity=kept,
        singularity_margin=request.singularity_margin, shoulder_margin=request.shoulder_margin,
        singularities_avoided=request.avoid_singularities, line_tolerance=request.line_tolerance,
        scene=base.scene_file, tool=base.tool,
        allowed_contacts=tuple(tuple(pair) for pair in base.allowed_contacts),
        joint_speeds=np.array(base.pricer.cost.speeds),
    )
