"""What to plan: the request, and the command line's inputs checked into one
(``PlanInputError`` naming the option, exit status 2)."""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbranch_gym.agents import BASELINES
from ikbranch_gym.agents.evaluation import ORACLE, parse_spec
from ikbranch_gym.envs.process import MAX_LIMIT

if TYPE_CHECKING:
    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
    from ikbranch_gym.envs.kinematics import Arm

#: The planner names ``--planner`` takes besides ``MODEL.zip``: the baselines
#: (``receding_dp:H``, ``fixed:BRANCH``, ``random:SEED`` take an argument).
PLANNERS = tuple(BASELINES)
#: Env arguments ``--env-kwargs`` may not set: they have options of their own (or are
#: fixed by the command).
RESERVED_ENV_KWARGS = ("arm", "arm_params", "scene", "scene_file", "scene_options", "task",
                       "task_file", "task_start", "task_points_abc", "task_segments",
                       "task_units", "task_columns", "task_skip_unreachable",
                       "max_joint_step", "singularity_margin", "shoulder_margin",
                       "tool_axis", "allowed_contacts", "tool", "joint_speeds",
                       "collision_resolution", "n_waypoints", "render_mode", "width", "height")


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
    #: Rows this near a singular configuration are flagged (rad: wrist and elbow; m:
    #: shoulder); with ``avoid_singularities`` no planner may take such a branch.
    singularity_margin: float = math.radians(5.0)
    shoulder_margin: float = 0.02
    avoid_singularities: bool = False
    #: Moves inside a segment whose TCP leaves the straight line by more than this (m)
    #: are flagged.
    line_tolerance: float = 0.001
    #: A free tool axis: (range, step) in rad, the tool turned about its axis by every
    #: multiple of step within ±range, and with a tilt cone (range, step, cone, cone_step)
    #: (None: fixed).
    tool_axis: tuple[float, ...] | None = None
    #: The unit of the file's x, y, z ("m", "mm"; None: its format's), and the further
    #: columns it carries, passed through to the plan's CSV.
    units: str | None = None
    extra_columns: tuple[str, ...] = ()
    #: Geom pairs (name patterns) that may touch: left out of every collision check.
    allowed_contacts: tuple[tuple[str, str], ...] = ()
    #: Leave out the rows no branch reaches, and plan the rest.
    skip_unreachable: bool = False
    #: The joint speeds moves are timed at: "rated" (the arm's data sheet), (dof,) rad/s
    #: or m/s, or None (the env's generic 1.5 rad/s, 0.5 m/s).
    joint_speeds: str | tuple[float, ...] | None = None

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
            "task_units": self.units,
            "task_columns": list(self.extra_columns) or None,
            "max_joint_step": self.max_joint_step,
        }
        if self.joint_speeds is not None:
            kwargs["joint_speeds"] = (self.joint_speeds if isinstance(self.joint_speeds, str)
                                      else list(self.joint_speeds))
        if self.tool_axis is not None:
            kwargs["tool_axis"] = list(self.tool_axis)
        if self.skip_unreachable:
            kwargs["task_skip_unreachable"] = True
        if self.allowed_contacts:
            kwargs["allowed_contacts"] = [list(pair) for pair in self.allowed_contacts]
        if self.avoid_singularities:
            kwargs["singularity_margin"] = self.singularity_margin
            kwargs["shoulder_margin"] = self.shoulder_margin
        return {**kwargs, **self.env_kwargs}


def make_env(request: PlanRequest) -> IKBranchEnv:
    """A fresh ``IKBranchEnv`` of the request (``ValueError`` for any bad input it finds)."""
    from ikbranch_gym.envs.ik_branch_env import IKBranchEnv

    return IKBranchEnv(**request.make_kwargs())



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


def parse_joint_speeds(text: str | None, arm: Arm) -> str | tuple[float, ...] | None:
    """``--joint-speeds``: ``rated``, ``generic`` or one speed per joint (deg/s, mm/s for a
    prismatic joint); default ``rated`` where the arm has a data sheet, else ``generic``.
    SI out."""
    from ikbranch_gym.envs.kinematics.speeds import rated_speeds

    word = "rated" if text is None and rated_speeds(arm) is not None else (text or "generic")
    word = word.strip()
    if word.lower() == "generic":
        return None
    if word.lower() == "rated":
        if rated_speeds(arm) is None:
            raise PlanInputError(f"--joint-speeds rated: {arm.name} has no data-sheet speeds; "
                                 f"give {arm.dof} speeds (deg/s, mm/s) or 'generic'")
        return "rated"
    try:
        values = [float(part) for part in word.split(",")]
    except ValueError:
        raise PlanInputError(f"--joint-speeds {text!r}: give 'rated', 'generic' or {arm.dof} "
                             "comma-separated speeds (deg/s, mm/s)") from None
    if len(values) != arm.dof:
        raise PlanInputError(f"--joint-speeds {text!r}: {len(values)} speeds for {arm.dof} "
                             "joints")
    if not all(math.isfinite(v) and v > 0.0 for v in values):
        raise PlanInputError(f"--joint-speeds {text!r}: every speed must be positive")
    return tuple(math.radians(v) if kind == "revolute" else v / 1000.0
                 for v, kind in zip(values, arm.joint_types, strict=True))


def parse_allowed_contact(text: str) -> tuple[str, str]:
    """``--allow-contact A:B``: two geom names or ``fnmatch`` patterns."""
    parts = text.split(":")
    if len(parts) != 2 or not all(part.strip() for part in parts):
        raise PlanInputError(f"--allow-contact {text!r}: give two geom names (or patterns) "
                             "joined by ':', e.g. tool:scene/part*")
    return parts[0].strip(), parts[1].strip()


def _degree_pair(text: str, option: str, form: str, example: str) -> tuple[float, float]:
    """``A:B`` in degrees as two angles in rad; ``PlanInputError`` naming ``option``."""
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        first, second = (math.radians(float(part)) for part in parts)
    except ValueError:
        raise PlanInputError(f"{option} {text!r}: give {form} in degrees, e.g. "
                             f"{example}") from None
    return first, second


def parse_tool_axis(text: str | None, tilt: str | None = None) -> tuple[float, ...] | None:
    """``--tool-axis RANGE:STEP`` and ``--tool-tilt CONE:STEP`` (degrees): (range, step)
    or (range, step, cone, cone_step) in rad, checked."""
    if tilt is not None:
        from ikbranch_gym.envs.tool_axis import MAX_SAMPLES, axis_angles, tilt_directions

        spin = parse_tool_axis(text) or (0.0, math.pi)
        cone, step = _degree_pair(tilt, "--tool-tilt", "CONE:STEP", "10:5 (tilts of 5° and "
                                  "10° around the axis)")
        try:
            count = len(axis_angles(*spin)) * len(tilt_directions(cone, step))
        except ValueError as exc:
            raise PlanInputError(f"--tool-tilt {tilt!r}: {exc}") from None
        if count > MAX_SAMPLES:
            raise PlanInputError(f"--tool-tilt {tilt!r}: with --tool-axis that is {count} "
                                 f"tool orientations; at most {MAX_SAMPLES} (larger steps)")
        return (*spin, cone, step)
    if text is None:
        return None
    half_range, step = _degree_pair(text, "--tool-axis", "RANGE:STEP",
                                    "180:15 (every 15° from −180° to 180°)")
    from ikbranch_gym.envs.tool_axis import axis_angles

    try:
        axis_angles(half_range, step)
    except ValueError as exc:
        raise PlanInputError(f"--tool-axis {text!r}: {exc}") from None
    return half_range, step


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


def _check_singularity_options(args: argparse.Namespace, arm: Arm) -> None:
    """``--singularity-margin``, ``--shoulder-margin``, ``--avoid-singularities``."""
    if not (math.isfinite(args.singularity_margin) and 0.0 <= args.singularity_margin < 90.0):
        raise PlanInputError(f"--singularity-margin must lie in [0, 90) degrees, got "
                             f"{args.singularity_margin!r}")
    if not (math.isfinite(args.shoulder_margin) and args.shoulder_margin >= 0.0):
        raise PlanInputError(f"--shoulder-margin must be a length >= 0 in mm, got "
                             f"{args.shoulder_margin!r}")
    if args.avoid_singularities:
        from ikbranch_gym.envs.kinematics.singularities import has_singularity_rules

        if not has_singularity_rules(arm):
            raise PlanInputError(f"--avoid-singularities: {arm.name} has no singularity rules "
                                 "(OPW and UR arms have them)")


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
                             "sets them from its own options (--arm, --waypoints, --scene, "
                             "--tool, --joint-speeds, …; see --help)")
    if args.points_abc is not None and any(not math.isfinite(v) for v in args.points_abc):
        raise PlanInputError(f"--points-abc must be finite lengths in mm, got {args.points_abc}")
    _check_singularity_options(args, arm)
    extra = [part.strip() for part in (args.extra_columns or "").split(",") if part.strip()]
    from .outputs import csv_columns

    taken = sorted(set(extra) & set(csv_columns(arm)))
    if taken:
        raise PlanInputError(f"--extra-columns: {', '.join(taken)} would be columns of the "
                             "plan itself")
    if not (math.isfinite(args.line_tolerance) and args.line_tolerance >= 0.0):
        raise PlanInputError(f"--line-tolerance must be a length >= 0 in mm, got "
                             f"{args.line_tolerance!r}")
    return PlanRequest(
        joint_speeds=parse_joint_speeds(args.joint_speeds, arm),
        skip_unreachable=bool(args.skip_unreachable),
        allowed_contacts=tuple(parse_allowed_contact(text)
                               for text in args.allowed_contacts or ()),
        units=args.units,
        extra_columns=tuple(extra),
        tool_axis=parse_tool_axis(args.tool_axis, args.tool_tilt),
        line_tolerance=args.line_tolerance / 1000.0,
        singularity_margin=math.radians(args.singularity_margin),
        shoulder_margin=args.shoulder_margin / 1000.0,
        avoid_singularities=bool(args.avoid_singularities),
        max_joint_step=parse_max_joint_step(args.max_joint_step),
        segments=parse_segments(args.segments),
        arm=args.arm, waypoints=waypoints, arm_params=arm_params,
        points_abc=None if args.points_abc is None else tuple(args.points_abc),
        scene=scene, scene_options=scene_options, tool=tool, tool_file=tool_file,
        start=start, planners=planners, resolution=float(args.resolution),
        env_kwargs=env_kwargs,
    )


def _check_program(option: str, path: Path, request: PlanRequest) -> None:
    """A controller program's language drives the arm, its file name is a program name."""
    from .controllers import check_family, program_name

    try:
        check_family(option[2:], request.arm)
        program_name(path.stem, option)
    except ValueError as exc:
        raise PlanInputError(str(exc)) from None


def output_paths(args: argparse.Namespace, request: PlanRequest) -> dict[str, Path]:
    """``--out``, ``--json``, ``--gif``, ``--map`` and the controller programs checked:
    the right suffix (a KRL program's ``.dat`` beside its ``.src``), an existing folder,
    a program name the controller accepts for an arm it drives, distinct from each other
    and from every input file."""
    from .controllers import SUFFIXES

    outputs = {"--out": Path(args.out)}
    for option, value in (("--json", args.json), ("--gif", args.gif), ("--map", args.map),
                          ("--krl", args.krl), ("--rapid", args.rapid),
                          ("--urscript", args.urscript)):
        if value:
            outputs[option] = Path(value)
    suffixes = {"--out": ".csv", "--json": ".json", "--gif": ".gif", "--map": ".png",
                **{f"--{language}": suffix for language, suffix in SUFFIXES.items()}}
    for option, path in list(outputs.items()):
        if path.suffix.lower() != suffixes[option]:
            raise PlanInputError(f"{option} {path}: the file name must end in "
                                 f"{suffixes[option]}")
        if option[2:] in SUFFIXES:
            _check_program(option, path, request)
        if option == "--krl":
            outputs["--krl (.dat)"] = path.with_suffix(".dat")
    for option, path in outputs.items():
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise PlanInputError(f"{option} {path}: folder {folder} does not exist")
        if path.is_dir():
            raise PlanInputError(f"{option} {path}: is a folder")
    resolved = [path.resolve() for path in outputs.values()]
    if len(set(resolved)) != len(resolved):
        raise PlanInputError("--out, --json, --gif, --map and the programs must name "
                             "different files")
    _check_not_inputs(outputs, request)
    return outputs


def _check_not_inputs(outputs: dict[str, Path], request: PlanRequest) -> None:
    """No output overwrites an input file."""
    inputs = [p for p in (request.waypoints, request.scene, request.tool_file) if p]
    for option, path in outputs.items():
        if any(path.resolve() == p.resolve() for p in inputs):
            raise PlanInputError(f"{option} {path} would overwrite an input file")
