"""The IK-branch selection environment (see :class:`IKBranchEnv`)."""

from __future__ import annotations

import numbers
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ikbranch_gym.envs.costs import TransitionCost
from ikbranch_gym.envs.episodes import EpisodeBatch, new_scene_token
from ikbranch_gym.envs.kinematics import ARM_NAMES, Arm, make_arm
from ikbranch_gym.envs.kinematics.singularities import has_singularity_rules
from ikbranch_gym.envs.models import SCENES, CollisionChecker, build_arm_model
from ikbranch_gym.envs.models.contacts import allow_contacts
from ikbranch_gym.envs.models.filter import CompiledFilter
from ikbranch_gym.envs.models.scene_file import base_pose, load_scene_file
from ikbranch_gym.envs.models.scenes import CLUTTER_SLOTS, ClutterSlots, draw_clutter
from ikbranch_gym.envs.moves import MovePricer, TaskMoves
from ikbranch_gym.envs.observations import ObservationBuilder
from ikbranch_gym.envs.process import check_limit, segment_index
from ikbranch_gym.envs.resets import RESET_OPTIONS, begin_episodes
from ikbranch_gym.envs.seeds import TRAIN_SCENES
from ikbranch_gym.envs.task_frame import FramedArm, TaskFrame
from ikbranch_gym.envs.tasks import TASKS, Task
from ikbranch_gym.envs.tasks.base import RangedArm
from ikbranch_gym.envs.tasks.file_task import FileTask
from ikbranch_gym.envs.tasks.waypoint_file import read_waypoints
from ikbranch_gym.envs.tool_axis import ToolAxisArm, axis_angles, tilt_directions
from ikbranch_gym.envs.tools import Tool

if TYPE_CHECKING:
    from ikbranch_gym.envs.render import SceneRenderer

#: ``scene_options`` placing the arm's base in the cell (m; unit quaternion or rpy, rad).
BASE_KEYS = ("base_pos", "base_quat", "base_rpy")
#: The ``scene_options`` each scene takes.
SCENE_OPTIONS: dict[str, tuple[str, ...]] = {
    "file": (*BASE_KEYS, "floor", "decompose", "coacd_options"),
    "milling_cell": BASE_KEYS,
}


def _integer(value: object, name: str, minimum: int) -> int:
    """``value`` as an int (numpy integers too), ``ValueError`` unless an integer >= minimum."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


#: Tasks made of process segments: where process continuity, a free tool axis and
#: singularity margins apply.
PROCESS_TASKS = ("file", "deburring")
_PROCESS = "task='file' or 'deburring' (process tasks)"


def _check_choices(arm: str, scene: str, task: str, render_mode: str | None) -> None:
    """``ValueError`` for a name the env does not know."""
    for what, value, known in (("arm", arm, ARM_NAMES), ("scene", scene, SCENES),
                               ("task", task, TASKS)):
        if value not in known:
            raise ValueError(f"unknown {what} {value!r}; choose one of {', '.join(known)}")
    if render_mode not in (None, *IKBranchEnv.metadata["render_modes"]):
        raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")


def _free_tool_axis(arm: Arm, tool: Tool | None, task: str, tool_axis: Any) -> Arm:
    """``arm`` with its tool free about the TCP's z axis (``tool_axis`` [range, step], or
    [range, step, cone, cone_step] with a tilt cone)."""
    if task not in PROCESS_TASKS:
        raise ValueError(f"tool_axis is for {_PROCESS}")
    if not (isinstance(tool_axis, list | tuple) and len(tool_axis) in (2, 4)):
        raise ValueError("tool_axis must be [range, step] or [range, step, cone, cone_step] "
                         f"in rad, got {tool_axis!r}")
    tilts = None if len(tool_axis) == 2 else tilt_directions(*tool_axis[2:])
    return cast(Arm, ToolAxisArm(arm, None if tool is None else tool.tcp,
                                 axis_angles(*tool_axis[:2]), tilts))


def _check_job_options(arm: Arm, task: str, max_joint_step: Any, singularity_margin: Any,
                       shoulder_margin: Any) -> None:
    """Process continuity and singularity margins: waypoint-file tasks only, values in
    range, margins only for arms with singularity rules."""
    if max_joint_step is not None:
        if task not in PROCESS_TASKS:
            raise ValueError(f"max_joint_step (process continuity) is for {_PROCESS}: "
                             "their waypoints form the process segments")
        if max_joint_step != "auto":
            check_limit(max_joint_step)
    for name, margin in (("singularity_margin", singularity_margin),
                         ("shoulder_margin", shoulder_margin)):
        if margin is None:
            continue
        if task not in PROCESS_TASKS:
            raise ValueError(f"{name} is for {_PROCESS}")
        if not has_singularity_rules(arm):
            raise ValueError(f"{name}: {arm.name} has no singularity rules (OPW and UR arms "
                             "have them)")
        angle = name == "singularity_margin"
        upper = np.pi / 2 if angle else np.inf
        if (isinstance(margin, bool) or not isinstance(margin, numbers.Real)
                or not 0.0 <= float(margin) < upper):
            raise ValueError(f"{name} must be a finite number >= 0"
                             + (" below π/2 (rad)" if angle else " (m)") + f", got {margin!r}")


def _joint_range(arm: Arm, task: str, joint_range: Any) -> np.ndarray:
    """``task_joint_range`` as a (dof, 2) array: the random task's only, one [low, high]
    per joint inside the arm's limits (rad, m)."""
    if task != "random":
        raise ValueError(f"task_joint_range is for task='random', not {task!r}")
    try:
        value = np.array(joint_range, dtype=np.float64)
    except (TypeError, ValueError):
        value = np.empty(0)
    if value.shape != (arm.dof, 2) or not np.all(np.isfinite(value)):
        raise ValueError(f"task_joint_range must be {arm.dof} pairs [low, high] of finite "
                         f"numbers (rad, m), got {joint_range!r}")
    limits = arm.joint_limits
    for j, (low, high) in enumerate(value):
        if not limits[j, 0] <= low < high <= limits[j, 1]:
            raise ValueError(f"task_joint_range: joint {j + 1}'s [{low}, {high}] is not a "
                             f"range inside its limits [{limits[j, 0]}, {limits[j, 1]}]")
    return value


def _check_numbers(collision_penalty: float, invalid_penalty: float,
                   collision_resolution: float, width: int, height: int) -> None:
    for name, value in (("collision_penalty", collision_penalty),
                        ("invalid_penalty", invalid_penalty)):
        if not np.isfinite(value) or value < 0:
            raise ValueError(f"{name} must be a finite number >= 0, got {value}")
    if not collision_resolution > 0:
        raise ValueError(f"collision_resolution must be positive, got {collision_resolution}")
    if width < 1 or height < 1:
        raise ValueError("width and height must be positive")


class IKBranchEnv(gym.Env):
    """Move an industrial arm through waypoints by choosing, at each one, an IK branch.

    ## Description
    An episode is a task: a start configuration and ``N`` waypoint poses. At every step the
    agent picks one of the arm's ``K`` closed-form inverse-kinematics branches (shoulder,
    elbow, wrist flip, …; ``arm.branch_labels``) for the next waypoint, and the arm moves
    there along the straight line in joint space. Joint travel costs reward (the paper's
    Σ|Δφ|, Klyuiko 1986), optionally move time, and a path that hits anything (obstacles,
    the arm itself, the other arm) costs a penalty. All ``N × K`` candidate configurations
    come from one batched IK call at reset.

    ## Action space
    ``Discrete(K)``: the branch for the next waypoint. ``action_masks()`` (sb3-contrib's
    protocol) marks the branches that exist and lie inside the joint limits, and every
    ``info`` of ``reset`` and ``step`` carries the same mask as ``info["action_mask"]`` (so
    a vector env batches it with no extra call); an unmasked agent may still pick an
    invalid one, which ends the episode with ``invalid_penalty``.

    **Process continuity** (``max_joint_step``, process tasks only: ``file`` and
    ``deburring``): a waypoint file's waypoints form process segments (its ``segment``
    column or blank lines, or ``task_segments``; a deburring pass is one), inside which
    no move may change the arm's configuration (its closed-form branch: shoulder, elbow,
    wrist) or step a revolute joint by more than
    ``max_joint_step`` rad (``"auto"``: derived from the task, ``envs/process.py``). Such a
    move is left out of the mask, and picking it anyway is an invalid branch; branches
    from which their segment cannot be followed are not valid at all, so the mask never
    empties for that reason; a segment that cannot be followed is a ``ValueError`` at
    reset naming where it breaks. Moves between segments may reconfigure.
    ``singularity_margin`` and ``shoulder_margin`` (OPW and UR arms, process tasks)
    leave out of the ladder every branch that near a singular configuration
    (``envs.kinematics.singularities``). A drawn task (the deburring pass) is drawn only
    where the arm can follow it within both: its search takes the env's limit and only
    configurations outside the margins.
    ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")`` advances N
    copies of this env together in one process, each the single env seeded s + i bit for
    bit (``envs.vector_env.IKBranchVectorEnv``; its docstring is its manual).

    ## Observation space
    One flat ``Box(-1, 1, float32)``: every SB3 algorithm's default MLP policy (PPO,
    MaskablePPO) takes it as is and vector envs copy one contiguous array;
    ``observation_layout`` names each slice (assembled by ``envs.observations``). Contents
    (joint values are normalised to [−1, 1] over their limits, travel to [0, 1] by the
    largest possible travel):

    - ``q``: the current configuration (dof); ``progress``: waypoints done / N.
    - For the next waypoint (slot 0) and each of ``lookahead`` later ones (slots 1…H):
      ``present`` (1: the slot is within the task), ``candidates`` (K × dof, 0 where
      invalid), ``valid`` (K), ``endpoint_collision`` (K: the candidate configuration itself
      touches something).
    - Slot 0 also: ``travel`` (K) from the current configuration and ``path_collision`` (K)
      along the path there. With ``checked_moves`` n the env checks these paths in order
      of least travel (ties: the lower branch) until n are free; the moves left unchecked
      read as colliding (1), here and in the onward values, and one taken is checked then
      and paid as it is (its reward is the reward with every move checked).
    - ``observation="compact"`` (the default; O(K) values, for arms with hundreds of
      branches): per branch of every slot ``travel_out``, the least travel to a free
      branch of the waypoint after; slots h ≥ 1 ``travel_in``, the least travel from a
      free branch of the waypoint before; slot 0 ``free_travel_out``, the least travel
      onward along a path the env has checked to be collision-free (1 where none is), and
      with ``onward_moves`` n ≥ 2 ``free_travel_onward``, the least travel of the next n
      moves along checked collision-free paths (over n × the scale; 1 where none is, so a
      branch whose every way on is blocked within n moves reads 1).
    - ``observation="ladder"`` (the v0/v1 ids; O(K²)): slots h ≥ 1 carry ``travel``
      (K × K) from every candidate of the waypoint before.
    - Beyond slot 0's paths and onward paths the lookahead shows endpoint collisions only;
      the DP oracle baseline sees every path.

    ## Rewards
    Per step, with every weight a constructor argument:
    ``reward = reward_travel + reward_time + reward_collision + reward_invalid +
    reward_unfinished`` where ``reward_travel = −travel_weight · Σ_j w_j |Δq_j|``
    (prismatic joints scaled by ``prismatic_scale`` rad/m), ``reward_time = −time_weight ·
    max_j |Δq_j| / v_j``, ``reward_collision = −collision_penalty`` if the path collides,
    ``reward_invalid = −invalid_penalty`` for an invalid branch, and, when either ends the
    episode early, ``reward_unfinished = −max_transition_cost`` for each waypoint left
    unvisited (an invalid branch leaves its own waypoint unvisited too). That is the
    dearest move possible, so neither crashing nor an invalid branch is ever cheaper than
    finishing, and with ``invalid_penalty ≥ collision_penalty`` an invalid branch is never
    cheaper than any valid one. ``info`` carries each term and the raw ``travel``
    (rad-equivalents) and ``time`` (s); the reward is exactly their sum.
    ``edge_rewards(i)`` gives the same prices for every move into waypoint i, for planners;
    all of them come from ``envs.moves`` (``env.pricer``, ``env.ladder``), which planners
    and baselines share.

    ## Starting state
    ``reset`` draws a task from the env's ``np_random`` (seed it with ``reset(seed=…)``);
    the arm stands at the task's start configuration. The ``random`` task draws a chain of
    collision-free configurations joined by collision-free paths inside the joint limits,
    or inside ``task_joint_range`` ([low, high] per joint): its first is the start, the
    poses of the others are the waypoints. With ``task="paper_transfer"`` the
    arm already stands at position 1: its first step only picks that branch, at no cost.
    With ``scene="random_clutter"`` and ``scene_seed=None`` every reset first lays a new
    clutter (its seed drawn from ``np_random`` in ``scene_seeds``, ``info["scene_seed"]``);
    scenes without clutter ignore ``scene_seed``. ``reset(options={"scene_seed": s,
    "task_seed": t})`` (either or both) lays clutter ``s`` instead of drawing one (ids that
    draw one per episode only), and draws the task from a generator seeded with ``t``
    (``info["task_seed"]``); ``np_random`` makes neither draw then. Any other key, or a
    value that is not an integer ≥ 0, is a ``ValueError``. With ``optimal_return=True``
    the DP oracle plans every episode at reset (its lazy path checks are the env's own,
    cached: nothing the episode observes or pays changes) and every ``info`` of the
    episode carries ``optimal_return``, the best return any masked action sequence gets,
    for regret curves.

    ## Episode end
    Terminates after the last waypoint, on an invalid branch, and on a colliding path when
    ``terminate_on_collision``. Episodes never run longer than ``N`` steps (no truncation).
    The ids register no ``max_episode_steps``: the env ends every episode itself, and a
    ``TimeLimit`` of ``N`` would mark that last step truncated as well, and would cut short
    the episodes of an ``n_waypoints`` passed to ``gym.make``; ``unwrapped.n_waypoints``
    is the length.
    ``info["is_success"]`` at the end: every waypoint reached, no collision, no invalid
    branch.

    ## Arguments
    ``gym.make("IKBranch/Anthropomorphic-v4", **kwargs)``; every argument is JSON-able.

    ===================== ======================= ===========================================
    argument              default                 meaning
    ===================== ======================= ===========================================
    arm                   "anthropomorphic"       a name in ``envs.kinematics.ARM_NAMES``
    scene                 "random_clutter"        a name in ``envs.models.scenes.SCENES``
    task                  "random"                a name in ``envs.tasks.TASKS``
    n_waypoints           None                    waypoints per episode (None: the task's)
    lookahead             2                       later waypoints shown (H ≥ 0)
    travel_weight         1.0                     weight of the joint travel (per rad)
    time_weight           0.0                     weight of the move time (per s)
    collision_penalty     10.0                    penalty of a colliding path
    invalid_penalty       10.0                    penalty of an invalid branch
    terminate_on_collision True                   end the episode on a colliding path
    prismatic_scale       1.0                     rad of travel per m of a prismatic joint
    joint_weights         None                    per-joint travel weights (None: all 1)
    joint_speeds          None                    list, None (1.5 rad/s, 0.5 m/s) or "rated"
    collision_resolution  0.01                    path-check clearance and step (m)
    collision_shapes      "drawn"                 "drawn", or "inscribed" (the earlier ids)
    scene_seed            0                       clutter seed (None: new every reset)
    scene_seeds           None                    [lo, hi) of those (None: the training range)
    arm_params            None                    dict of arm parameters (``make_arm``)
    observation           "compact"               "compact" (O(K)) or "ladder" (O(K²), v0/v1)
    onward_moves          1                       ≥ 2: free_travel_onward over so many moves
    checked_moves         None                    check moves until so many are free (None: all)
    task_file             None                    ``task="file"``: a waypoint file (CSV/JSON)
    task_start            None                    its start q (None: free first branch)
    task_points_abc       None                    four-point files: a, b, c (mm)
    task_segments         None                    first waypoints of its process segments
    task_units            None                    "m" or "mm": of its x, y, z (None: the format's)
    task_columns          None                    further columns it may carry (passed through)
    task_skip_unreachable False                   leave out the rows no branch reaches
    task_joint_range      None                    random task: [low, high] per joint (None: limits)
    max_joint_step        None                    process continuity: step limit (rad), "auto"
    singularity_margin    None                    no branch this near a wrist/elbow singular (rad)
    shoulder_margin       None                    no branch this near the shoulder singularity (m)
    tool_axis             None                    [range, step(, cone, cone_step)] rad: free axis
    allowed_contacts      None                    geom pairs (name patterns) that may touch
    scene_file            None                    ``scene="file"``: an MJCF file of the cell
    scene_options         None                    base_pos/_quat/_rpy, floor, decompose, …
    tool                  None                    a tool (``envs/tools.py``); None: built-in
    render_mode           None                    None or "rgb_array"
    width                 480                     rendered frame width (px)
    height                360                     rendered frame height (px)
    optimal_return        False                   ``info["optimal_return"]``: DP's optimum
    ===================== ======================= ===========================================

    ## Version history
    - KukaKR6Deburring **-v1** (2026-12-07): the pass keeps one configuration: inside it
      only moves within 30° on every joint are in the mask (``max_joint_step``). A reset
      solves its waypoints in one call with the other resetting envs', and the ladder it
      made from them left out the step limit (and the singularity margins): -v0 never
      applied its limit, so its mask offers moves that reconfigure the arm mid-pass. -v0
      stays registered, unchanged, for its published models; its spec now names no
      limit, which is what it always did.
    - UR5e **-v4** (2026-12-06): the random task draws its chain of configurations (the
      start, and the configurations whose poses are the waypoints) within one turn of each
      joint's zero (``task_joint_range`` [−π, π] for every joint), where UR5e-v3 draws them
      anywhere in the ±2π limits. Every turn of every waypoint stays a branch to choose
      (256). Chains whose paths turned joints by up to two revolutions collided so often
      that drawing a task was about half of a reset. Scenes, observations, rewards and
      collision verdicts are UR5e-v3's, which stays registered for its published models.
      ``task_joint_range`` is a new argument of every id whose task is ``random`` (None,
      the arm's limits, by default).
    - KukaKR6 **-v2** (2026-12-05): the observation also shows, per branch of the next
      waypoint, the least travel of the next two moves along paths the env has checked to
      be collision-free (``onward_moves=2``, ``free_travel_onward``), as Anthropomorphic-v4
      and UR5e-v2 do: a branch whose every free move on leads into a branch with no free
      move after it reads 1. Tasks, scenes, rewards and collision verdicts are
      KukaKR6-v1's, which stays registered for its published models.
    - UR5e **-v3** (2026-12-05): the env checks the moves into the next waypoint in order
      of least travel until eight are free (``checked_moves``), where UR5e-v2 checks all
      256 paths; the moves left unchecked read as colliding, and one taken is checked then
      and paid as it is. Tasks, scenes, rewards and collision verdicts are UR5e-v2's,
      which stays registered for its published models. ``checked_moves`` is a new
      argument for every id (None, every move checked, by default).
    - Anthropomorphic **-v4**, UR5e **-v2** (2026-12-04): the observation also shows, per
      branch of the next waypoint, the least travel of the next three (Anthropomorphic) or
      two (UR5e) moves along paths the env has checked to be collision-free
      (``onward_moves``, ``free_travel_onward``): a branch from which every way on is
      blocked within them reads 1. Tasks, scenes, rewards and collision verdicts are those
      of Anthropomorphic-v3 and UR5e-v1, which stay registered for their published models.
      ``onward_moves`` is a new argument for every id (1, as before, by default).
    - KukaKR6Deburring **-v0** (2026-12-04): a process job on a real arm. A KR 6 R700
      deburrs the rim of a part clamped in a fixture (scene ``deburring_cell``, task
      ``deburring``): one pass of 12 rim points an episode, its chamfer angle drawn, the
      burr free about its axis (the action is branch × spin, 160), one configuration along
      the pass (``max_joint_step`` 30°), the burr allowed to touch the part.
    - Same ids, same behaviour (2026-12-04): ``joint_speeds="rated"`` times moves at the
      real arm's data-sheet joint speeds (KR 6 R700, IRB 2400/2600/4600, UR5e, UR10e);
      ``tool_axis`` takes a tilt cone, [range, step, cone, cone_step]: the tool's axis may
      also tilt by up to the cone in any direction.
    - Same ids, same behaviour (2026-12-04): process continuity for waypoint-file tasks,
      the new arguments ``max_joint_step`` and ``task_segments`` (off by default); waypoint
      files may carry a ``segment`` column; ``singularity_margin`` and ``shoulder_margin``
      keep branches away from singular configurations, ``tool_axis`` lets a round tool
      turn about its axis (its angles join the branches), ``allowed_contacts`` leaves
      named geom pairs out of the collision checks; all off by default. A random task
      draws up to 2,000 rounds of configurations (was 50) before it calls a clutter too
      tight: no task found before changes, and a dense UR5e clutter no longer stops a
      training run.
    - The current generation (2026-12-04): Cartesian, Cylindrical, Spherical,
      Anthropomorphic, Cylindrical4 **-v3**, ToolTransfer **-v2**, DualRRPRPP, DualRRRPPP,
      DualPPRPRR **-v2**, RodMechanism **-v3**, KukaKR6, UR5e, IRB4600ToolTransfer,
      IRB2600Screwing **-v1**: every collision shape is the drawn shape
      (``collision_shapes="drawn"``): cylinders are collided as cylinders (before: as the
      capsule inside them, a disc as the box around it), and only a joint's own two sides
      are excluded from each other (before: the overlapping parts of wrists and guides
      too), so the wrists' roll housings end farther behind the wrist centre, the
      cylindrical arms' radial slide is a fork of two rails beside the column and the
      spherical arm's boom swings between two cheeks. A move these ids call free keeps
      every drawn part apart all along it (certified by a second collision library in the
      tests). Observations, rewards and tasks are made as before; verdicts change where
      the shapes did. The ids before stay registered, unchanged
      (``collision_shapes="inscribed"``), for their published models.
    - Same ids, same behaviour (2026-12-03): ``reset(options=…)`` takes ``scene_seed`` and
      ``task_seed`` (options were ignored before; any other key is now an error); the
      opt-in ``optimal_return`` argument; the package is imported as ``ikbranch_gym``
      (``gym.make("ikbranch_gym:IKBranch/…")`` needs no import of its own).
    - Same ids, same behaviour (2026-12-03): every ``info`` carries ``action_mask``; every
      id registers a natively batched vector env (``vector_entry_point``); collision
      checks prove contacts from inner shapes as well as freedom from bounds, so MuJoCo is
      called only where neither proof holds (verdicts and first colliding samples are
      MuJoCo's, as before: observations and rewards are unchanged, tested as streams of
      steps on every id).
    - The compact generation: Cartesian, Cylindrical, Spherical, Anthropomorphic,
      Cylindrical4 **-v2**, ToolTransfer **-v1**, DualRRPRPP, DualRRRPPP, DualPPRPRR **-v1**,
      RodMechanism **-v2**, and the industrial arms (real limits, every turn branch)
      KukaKR6 **-v0**, UR5e **-v0** (random clutter), IRB4600ToolTransfer **-v0** (the
      milling cell's tool changes, a gripper holding the tool) and IRB2600Screwing **-v0**
      (a nut runner whose j6 must unwind): the compact observation (O(K): least travel into
      and out of each branch instead of K × K travel blocks); the random-clutter ids draw a
      new clutter at every reset (``scene_seed=None``, seeds from ``scene_seeds``, training
      and held-out ranges in ``envs/seeds.py``; obstacles are primitive boxes and capsules,
      moved without a recompile); the dual-arm ids' tasks sweep along a collision-free
      straight path (``relative_motion_free``), so every task has a collision-free solution.
      The older ids stay registered, unchanged, for their published models.
    - Same ids, same behaviour (2026-12-01): collision checks run through a compiled
      filter that decides exactly as before (``envs/models/filter/``), and the sample
      grid of a path is summed in joint order for every backend; the published results
      re-evaluate unchanged.
    - v1 (the random-waypoint ids: Cartesian, Cylindrical, Spherical, Anthropomorphic,
      Cylindrical4, RodMechanism): the ``random`` task guarantees a collision-free solution
      (the straight path between consecutive generating configurations is checked); v0
      only guaranteed collision-free waypoint configurations, and 8 % of
      Anthropomorphic-v0's tasks could not be done without a collision. The other ids stay
      v0.
    - All ids, with v1: collision boxes are convex meshes and MuJoCo's midphase is off, so
      every pair closer than ``collision_resolution`` is reported (two MuJoCo behaviours
      had let a few near misses through; ``envs/models/collision.py``). Published
      numbers were re-measured.
    - v0: initial release.
    """

    # Gymnasium's Env declares metadata a plain attribute (no ClassVar), as here.
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 4}  # noqa: RUF012
    #: The arm tasks are drawn for: ``arm`` in the task frame (``FramedArm``), inside
    #: ``task_joint_range`` (``RangedArm``).
    _task_arm: Arm

    def __init__(
        self,
        arm: str = "anthropomorphic",
        scene: str = "random_clutter",
        task: str = "random",
        n_waypoints: int | None = None,
        lookahead: int = 2,
        travel_weight: float = 1.0,
        time_weight: float = 0.0,
        collision_penalty: float = 10.0,
        invalid_penalty: float = 10.0,
        terminate_on_collision: bool = True,
        prismatic_scale: float = 1.0,
        joint_weights: list[float] | None = None,
        joint_speeds: list[float] | str | None = None,
        collision_resolution: float = 0.01,
        collision_shapes: str = "drawn",
        scene_seed: int | None = 0,
        scene_seeds: list[int] | None = None,
        arm_params: dict[str, Any] | None = None,
        observation: str = "compact",
        onward_moves: int = 1,
        checked_moves: int | None = None,
        task_file: str | None = None,
        task_start: list[float] | None = None,
        task_points_abc: list[float] | None = None,
        task_segments: list[int] | None = None,
        task_units: str | None = None,
        task_columns: list[str] | None = None,
        task_skip_unreachable: bool = False,
        task_joint_range: list[list[float]] | None = None,
        max_joint_step: float | str | None = None,
        singularity_margin: float | None = None,
        shoulder_margin: float | None = None,
        tool_axis: list[float] | None = None,
        allowed_contacts: list[list[str]] | None = None,
        scene_file: str | None = None,
        scene_options: dict[str, Any] | None = None,
        tool: dict[str, Any] | None = None,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        optimal_return: bool = False,
    ) -> None:
        self._kwargs = {
            key: value for key, value in locals().items() if key not in ("self", "__class__")
        }
        _check_choices(arm, scene, task, render_mode)
        _check_numbers(collision_penalty, invalid_penalty, collision_resolution, width, height)
        self.arm = make_arm(arm, **(arm_params or {}))
        self.tool = None if tool is None else Tool.from_spec(tool)
        #: The arm as built and simulated (``self.arm`` with a free tool axis is a
        #: ``ToolAxisArm`` around it: its branches × the tool's angles).
        self.kinematic_arm = self.arm
        if tool_axis is not None:
            self.arm = _free_tool_axis(self.arm, self.tool, task, tool_axis)
        self.render_mode, self.scene = render_mode, scene
        self.lookahead = _integer(lookahead, "lookahead", 0)
        scene_kwargs = self._place_arm(scene, scene_file, scene_options)
        self._generator = self._task_generator(task, task_file, task_start, task_points_abc,
                                               task_segments, task_units, task_columns,
                                               task_skip_unreachable)
        if task_joint_range is not None:
            self._task_arm = cast(Arm, RangedArm(
                self._task_arm, _joint_range(self.arm, task, task_joint_range)))
        _check_job_options(self.kinematic_arm, task, max_joint_step, singularity_margin,
                           shoulder_margin)
        self._generator.check_arm(self._task_arm, scene)
        self.n_waypoints = self._waypoint_count(task, n_waypoints)
        draws_scenes = self._scene_seeds(scene, scene_seed, scene_seeds)
        if scene == "random_clutter":
            scene_kwargs = {"seed": scene_seed}
        self.model = build_arm_model(self.kinematic_arm, scene, tool=self.tool,
                                     collision_shapes=collision_shapes, **scene_kwargs)
        #: The geom pairs left out of the collision checks (``envs/models/contacts.py``).
        self.allowed_contacts = ([] if allowed_contacts is None
                                 else allow_contacts(self.model, allowed_contacts))
        #: The per-episode clutter's obstacle slots (``scene_seed=None``), else None.
        self._clutter = ClutterSlots(self.model, CLUTTER_SLOTS) if draws_scenes else None
        #: The seed of the clutter standing now (None: the scene is fixed).
        self.scene_seed: int | None = None
        checker = CollisionChecker(self.model, dof=self.arm.dof, resolution=collision_resolution)
        cost = TransitionCost.for_arm(
            self.arm, travel_weight=travel_weight, time_weight=time_weight,
            prismatic_scale=prismatic_scale, joint_weights=joint_weights,
            joint_speeds=joint_speeds,
        )
        #: Prices every move (shared with planners and baselines; owns the caches).
        self.pricer = MovePricer(
            self.arm, checker, cost, collision_penalty=collision_penalty,
            invalid_penalty=invalid_penalty, terminate_on_collision=terminate_on_collision,
            max_joint_step=max_joint_step, singularity_margin=singularity_margin,
            shoulder_margin=shoulder_margin,
        )
        self._observations = ObservationBuilder(
            self.arm, self.lookahead, self.pricer.travel_scale, observation,
            _integer(onward_moves, "onward_moves", 1),
            None if checked_moves is None else _integer(checked_moves, "checked_moves", 1),
        )
        self.observation_layout = self._observations.layout
        self.observation_space = spaces.Box(
            -1.0, 1.0, shape=(self._observations.size,), dtype=np.float32
        )
        self.action_space = spaces.Discrete(self.arm.n_branches)
        self._renderer: SceneRenderer | None = None
        #: The episode's state, stepped as a vector env steps its rows (a batch of one).
        self._episode = EpisodeBatch(1, self.n_waypoints, self.pricer, self._observations,
                                     self.compiled_filter, scenes=np.zeros(1, dtype=np.int64))
        self._episode.q[0] = self.arm.home
        self._row = np.zeros(1, dtype=np.int64)

        self.task: Task | None = None
        #: The current task's ladder (candidates and prices), None before ``reset``.
        self.ladder: TaskMoves | None = None
        #: With ``optimal_return=True``: the DP oracle's return of the current episode
        #: (``info["optimal_return"]``); else None.
        self.optimal_return: float | None = None
        self._plans_optimum = bool(optimal_return)

    # -------------------------------------------------------------- construction steps
    def _place_arm(self, scene: str, scene_file: str | None,
                   scene_options: dict[str, Any] | None) -> dict[str, Any]:
        """Check the scene's file and options, set ``scene_file`` (the loaded file or
        None), ``task_frame`` and the arm tasks speak to; returns the scene builder's
        keyword arguments (``random_clutter``'s seed is added by the caller)."""
        if (scene == "file") != (scene_file is not None):
            raise ValueError("scene='file' and scene_file=PATH go together")
        if scene_options is not None and scene not in SCENE_OPTIONS:
            raise ValueError("scene_options are for scene='file' and 'milling_cell'")
        options = dict(scene_options or {})
        unknown = sorted(set(options) - set(SCENE_OPTIONS.get(scene, ())))
        if unknown:
            raise ValueError(f"unknown scene_options {unknown} for scene {scene!r}; it takes "
                             f"{', '.join(SCENE_OPTIONS[scene])}")
        #: The scene file (its base pose maps its cell frame to the arm's), or None.
        self.scene_file = None if scene_file is None else load_scene_file(
            scene_file, **{k: v for k, v in options.items() if k not in ("floor",)})
        if self.scene_file is not None:
            cell_from_base = self.scene_file.base_pose
        else:
            cell_from_base = base_pose(**{k: options[k] for k in BASE_KEYS if k in options})
        #: Task poses are in the cell, of the tool's TCP: this maps them to the fk frame.
        self.task_frame = TaskFrame(cell_from_base,
                                    None if self.tool is None else self.tool.tcp)
        # A FramedArm answers everything an Arm does (fk and ik in the task frame, the
        # rest the arm's own), so tasks and chains take it as the arm.
        self._task_arm = (self.arm if self.task_frame.identity
                          else cast(Arm, FramedArm(self.arm, self.task_frame)))
        if scene == "file":
            return {"scene_file": scene_file, **options}
        return options if scene == "milling_cell" else {}

    def _task_generator(self, task: str, task_file: str | None,
                        task_start: list[float] | None,
                        task_points_abc: list[float] | None,
                        task_segments: list[int] | None, task_units: str | None = None,
                        task_columns: list[str] | None = None,
                        task_skip_unreachable: bool = False) -> Any:
        if (task == "file") != (task_file is not None):
            raise ValueError("task='file' and task_file=PATH go together")
        if task_file is not None:
            return self._file_task(task_file, task_start, task_points_abc, task_segments,
                                   task_units, task_columns, bool(task_skip_unreachable))
        if task_skip_unreachable or any(value is not None for value in (
                task_start, task_points_abc, task_segments, task_units, task_columns)):
            raise ValueError("task_start, task_points_abc, task_segments, task_units, "
                             "task_columns and task_skip_unreachable are for task='file'")
        return TASKS[task]

    def _waypoint_count(self, task: str, n_waypoints: int | None) -> int:
        generator = self._generator
        count = _integer(generator.default_waypoints if n_waypoints is None else n_waypoints,
                         "n_waypoints", 1)
        if getattr(generator, "fixed_waypoints", False) and count != generator.default_waypoints:
            raise ValueError(f"task {task!r} has exactly {generator.default_waypoints} "
                             f"waypoints, got n_waypoints={n_waypoints!r}")
        return count

    def _scene_seeds(self, scene: str, scene_seed: int | None,
                     scene_seeds: list[int] | None) -> bool:
        """Check the clutter seed arguments, set ``scene_seeds``; True when a new clutter
        is drawn at every reset. Scenes without clutter take any ``scene_seed`` (an id
        that draws clutter may be asked for another scene) and ignore it."""
        if scene_seed is not None:
            _integer(scene_seed, "scene_seed", 0)
        seeds = TRAIN_SCENES if scene_seeds is None else tuple(scene_seeds)
        if len(seeds) != 2 or not 0 <= _integer(seeds[0], "scene_seeds[0]", 0) < _integer(
                seeds[1], "scene_seeds[1]", 1):
            raise ValueError(f"scene_seeds must be [lo, hi) with 0 <= lo < hi, got {scene_seeds!r}")
        self.scene_seeds = (int(seeds[0]), int(seeds[1]))
        return scene == "random_clutter" and scene_seed is None

    def _file_task(self, path: str, start: list[float] | None,
                   abc: list[float] | None, segments: list[int] | None = None,
                   units: str | None = None, columns: list[str] | None = None,
                   skip_unreachable: bool = False) -> FileTask:
        """The task of a waypoint file: poses in the cell frame when a scene file gives one
        (else the arm's base frame), of the tool's TCP when a tool is given (else of the fk
        frame). ``ValueError`` naming every row no branch reaches, and why."""
        FileTask.check_arm(self._task_arm, "file")  # before the rows: a position-only arm
        a, b, c = (None, None, None) if abc is None else abc
        waypoints = read_waypoints(path, a=a, b=b, c=c, units=units,
                                   extra_columns=tuple(columns or ()))
        poses = waypoints.poses
        start_q = None
        if start is not None:
            start_q = np.asarray(start, dtype=np.float64)
            if start_q.shape != (self.arm.dof,) or not np.isfinite(start_q).all():
                raise ValueError(f"task_start must be {self.arm.dof} finite joint values")
            if not self.arm.within_limits(start_q):
                raise ValueError(f"task_start {start_q.tolist()} lies outside the joint limits")
        if segments is not None and (not isinstance(segments, list | tuple) or not all(
                isinstance(s, int | np.integer) and not isinstance(s, bool) for s in segments)):
            raise ValueError(f"task_segments must be a list of waypoint indices, got "
                             f"{segments!r}")
        task = FileTask(waypoints, poses, start_q, None if segments is None
                        else segment_index(len(poses), segments))
        problems = task.unreachable_rows(self._task_arm)
        #: The rows left out (``task_skip_unreachable``): their reasons.
        self.skipped_rows = [problem for _, problem in problems]
        if problems and (not skip_unreachable or len(problems) == len(poses)):
            raise ValueError(f"{len(problems)} of {len(poses)} waypoints cannot be reached "
                             f"by {self.arm.name}:\n  " + "\n  ".join(self.skipped_rows))
        if problems:
            unreachable = {row for row, _ in problems}
            task = task.keeping(np.array([w for w in range(len(poses))
                                          if w not in unreachable]))
        return task

    # ------------------------------------------------------------------ shared pieces
    @property
    def cost(self) -> TransitionCost:
        return self.pricer.cost

    @property
    def checker(self) -> CollisionChecker:
        return self.pricer.checker

    @property
    def compiled_filter(self) -> CompiledFilter:
        """The checker's compiled filter, which the episode's kernels call."""
        checks = self.checker._filter
        if checks is None:  # the env builds its checker with the compiled backend
            raise RuntimeError("the env's collision checker has no compiled filter")
        return checks

    @property
    def collision_penalty(self) -> float:
        return self.pricer.collision_penalty

    @property
    def invalid_penalty(self) -> float:
        return self.pricer.invalid_penalty

    @property
    def terminate_on_collision(self) -> bool:
        return self.pricer.terminate_on_collision

    @property
    def max_transition_cost(self) -> float:
        return self.pricer.max_transition_cost

    @property
    def q(self) -> np.ndarray:
        """(dof,) the arm's configuration now (a copy)."""
        return self._episode.q[0].copy()

    @property
    def index(self) -> int:
        """The next waypoint (``task.n_waypoints`` once the episode is over)."""
        return int(self._episode.index[0])

    @property
    def episode_collided(self) -> bool:
        """A move of this episode collided."""
        return bool(self._episode.collided[0])

    @property
    def episode_invalid(self) -> bool:
        """A move of this episode picked an invalid branch."""
        return bool(self._episode.invalid[0])

    @property
    def candidates(self) -> np.ndarray | None:
        """(N, K, dof) IK candidates of the task's waypoints (NaN rows where invalid)."""
        return None if self.ladder is None else _read_only(self.ladder.candidates)

    @property
    def valid(self) -> np.ndarray | None:
        """(N, K) bool: the branch exists and lies inside the joint limits."""
        return None if self.ladder is None else _read_only(self.ladder.valid)

    @property
    def endpoint_collision(self) -> np.ndarray | None:
        """(N, K) bool: the candidate configuration itself touches something."""
        return None if self.ladder is None else _read_only(self.ladder.endpoint_collision)

    # ---------------------------------------------------------------------------- API
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Begin an episode; ``options`` may hold ``scene_seed`` (lay that clutter: ids that
        draw one per episode) and ``task_seed`` (draw the task from a generator seeded
        with it); the env's ``np_random`` then makes neither of those draws."""
        info = begin_episodes([self], [seed], self.compiled_filter,
                              np.zeros(1, dtype=np.int64), [self.reset_options(options)])[0]
        self._episode.survey(self._row)
        info["action_mask"] = self._episode.masks(self._row)[0]
        return self._episode.observation[0].copy(), info

    def reset_options(self, options: dict | None) -> dict[str, int]:
        """``options`` of ``reset`` checked: ``ValueError`` for a key other than
        ``scene_seed`` and ``task_seed``, a value that is not an integer ≥ 0, or a
        ``scene_seed`` for an env that does not draw its clutter per episode."""
        if options is None:
            return {}
        if not isinstance(options, dict):
            raise ValueError(f"reset options must be a dict, got {type(options).__name__}")
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise ValueError(f"unknown reset options {unknown}; the env takes "
                             f"{', '.join(RESET_OPTIONS)}")
        checked = {key: _integer(value, key, 0) for key, value in options.items()
                   if value is not None}
        if "scene_seed" in checked and self._clutter is None:
            raise ValueError("reset option scene_seed needs an env that lays a clutter per "
                             "episode (scene='random_clutter', scene_seed=None)")
        return checked

    def _reset_scene(self, seed: int | None, scene_seed: int | None = None) -> dict:
        """A reset's first part: seed the env's generator and lay a new clutter where the
        env draws one per episode (``scene_seed``'s, else one drawn from ``np_random``).
        Returns the reset's ``info`` so far."""
        super().reset(seed=seed)
        if self._clutter is not None:
            if scene_seed is None:
                scene_seed = int(self.np_random.integers(*self.scene_seeds))
            self._lay_scene(scene_seed)
        info: dict[str, Any] = {"waypoint": 0}
        if self._clutter is not None:
            info["scene_seed"] = self.scene_seed
        return info

    def _in_fk_frame(self, task: Task) -> Task:
        """``task`` with its poses in the fk frame (tasks speak in the cell, of the TCP)."""
        if self.task_frame.identity:
            return task
        return Task(start=task.start, poses=self.task_frame.to_fk(task.poses),
                    free_start=task.free_start, segments=task.segments)

    def _lay_scene(self, seed: int) -> None:
        """Stand the clutter of scene ``seed`` in the model (the env's and the checker's),
        without the obstacles that would touch the arm at home, as a fixed scene drops
        them; every cached verdict belonged to the scene before."""
        if seed == self.scene_seed:
            return
        clutter, checker = self._clutter, self.checker
        if clutter is None:
            raise RuntimeError("only an env that draws its clutter per episode lays scenes")
        obstacles = draw_clutter(self.arm, seed, clutter.base, CLUTTER_SLOTS)
        clutter.lay(obstacles, self.model, checker.model)
        checker.refresh_static(clutter.geoms)
        if checker.collides(self.arm.home):
            touching = checker.contact_bodies(self.arm.home)
            obstacles = [o for o in obstacles if f"clutter{o.slot}" not in touching]
            clutter.lay(obstacles, self.model, checker.model)
            checker.refresh_static(clutter.geoms)
        self.pricer.clear_caches()
        self._episode.set_scene(0, new_scene_token())
        self.scene_seed = seed

    def _start(self, task: Task, ladder: TaskMoves) -> None:
        self.task, self.ladder = task, ladder
        self._episode.begin(0, ladder, self._observations.templates(ladder))
        if self._plans_optimum:
            # The planner checks paths through this env's own pricer: exact verdicts,
            # cached, so what the episode observes and pays is unchanged.
            from ikbranch_gym.agents.dp import plan_episode

            self.optimal_return = plan_episode(ladder)[2]

    def action_masks(self) -> np.ndarray:
        """(K,) bool: the branches of the next waypoint that exist and lie inside the
        limits (every branch once the episode is over: any action then)."""
        if self.task is None:
            raise RuntimeError("call reset() before action_masks()")
        return self._episode.masks(self._row)[0]

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self.task is None:
            raise RuntimeError("call reset() before step()")
        if self.index >= self.task.n_waypoints:
            raise RuntimeError("the episode has ended: call reset()")
        branch = int(action)
        if branch != action or not 0 <= branch < self.arm.n_branches:
            raise ValueError(f"action must be a branch index in [0, {self.arm.n_branches})")
        steps = self._episode.advance(self._row, np.array([branch]))
        info = steps.info(0)
        if self.optimal_return is not None:
            info["optimal_return"] = self.optimal_return
        self._episode.survey(self._row)
        info["action_mask"] = self._episode.masks(self._row)[0]
        return (self._episode.observation[0].copy(), float(steps.reward[0]),
                bool(steps.terminated[0]), False, info)

    def edge_rewards(self, waypoint: int) -> tuple[np.ndarray, np.ndarray]:
        """Reward and termination of every move into ``waypoint``, as ``step`` pays them.

        Rows are the configurations the arm can stand in before the move: the task's start
        for waypoint 0, else the K candidates of ``waypoint − 1`` (rows of invalid ones are
        NaN); columns the K branches of ``waypoint``. Returns ``reward`` (R, K) and
        ``terminal`` (R, K) bool. Every path is collision-checked (and cached), so this is
        what an oracle with full knowledge of the task plans over (``self.ladder`` prices
        moves lazily for planners that need fewer checks).
        """
        if self.ladder is None:
            raise RuntimeError("call reset() before edge_rewards()")
        return self.ladder.edges(waypoint)

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            from ikbranch_gym.envs.render import SceneRenderer

            self._renderer = SceneRenderer(
                self.model,
                width=self._kwargs["width"],
                height=self._kwargs["height"],
                frame_qs=[self.arm.home],
            )
        return self._renderer.render(self.q)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ---------------------------------------------------------------------- pickling
    def __getstate__(self) -> dict:
        # The task's IK solutions travel with it: the copy continues bit for bit, and
        # does not redo the IK and endpoint checks.
        ladder = self.ladder
        return {
            "kwargs": self._kwargs,
            "rng": None if self._np_random is None else self._np_random.bit_generator.state,
            "task": self.task,
            "solutions": None if ladder is None else (
                ladder.candidates, ladder.valid, ladder.endpoint_collision,
                ladder.continuity),
            "q": self.q,
            "branch": int(self._episode.branch[0]),
            "index": self.index,
            "flags": (self.episode_collided, self.episode_invalid),
            "scene_seed": self.scene_seed,
        }

    def __setstate__(self, state: dict) -> None:
        IKBranchEnv.__init__(self, **state["kwargs"])
        if state.get("scene_seed") is not None:
            self._lay_scene(state["scene_seed"])
        if state["rng"] is not None:
            self._np_random = np.random.Generator(np.random.PCG64())
            self._np_random.bit_generator.state = state["rng"]
        if state["task"] is not None:
            self._start(state["task"], TaskMoves(self.pricer, state["task"], *state["solutions"]))
        episode = self._episode
        episode.q[0], episode.index[0] = state["q"], state["index"]
        episode.branch[0] = state["branch"]
        episode.collided[0], episode.invalid[0] = state["flags"]
        if state["task"] is not None:
            episode.survey(self._row)


def _read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array``: a ladder's arrays are shared by every ladder of the
    same task (``MovePricer.task``), so what the env hands out must not write to them."""
    view = array.view()
    view.flags.writeable = False
    return view
