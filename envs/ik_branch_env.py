"""The IK-branch selection environment (see :class:`IKBranchEnv`)."""

from __future__ import annotations

import numbers
import os

os.environ.setdefault("MUJOCO_GL", "egl")

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from envs.costs import TransitionCost
from envs.kinematics import ARM_NAMES, make_arm
from envs.models import SCENES, CollisionChecker, build_arm_model
from envs.tasks import TASKS, Task

#: Path-collision results kept per env (the milling cell's finite pose set fits many times).
PATH_CACHE_SIZE = 200_000
#: Waypoint poses whose IK candidates (and their endpoint collisions) are kept per env: a
#: task with a finite pose set (the milling cell's tool changes) solves each pose once.
POSE_CACHE_SIZE = 50_000


def _integer(value, name: str, minimum: int) -> int:
    """``value`` as an int (numpy integers too), ``ValueError`` unless an integer >= minimum."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


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
    protocol) marks the branches that exist and lie inside the joint limits; an unmasked
    agent may still pick an invalid one, which ends the episode with ``invalid_penalty``.

    ## Observation space
    One flat ``Box(-1, 1, float32)``: every SB3 algorithm's default MLP policy (PPO,
    MaskablePPO) takes it as is and vector envs copy one contiguous array;
    ``observation_layout`` names each slice. Contents (joint values are normalised to
    [−1, 1] over their limits, travel to [0, 1] by the largest possible travel):

    - ``q``: the current configuration (dof); ``progress``: waypoints done / N.
    - For the next waypoint (slot 0) and each of ``lookahead`` later ones (slots 1…H):
      ``present`` (1: the slot is within the task), ``candidates`` (K × dof, 0 where
      invalid), ``valid`` (K), ``endpoint_collision`` (K: the candidate configuration itself
      touches something).
    - Slot 0 also: ``travel`` (K) from the current configuration and ``path_collision`` (K)
      along the path there. Slots h ≥ 1: ``travel`` (K × K) from every candidate of the
      waypoint before. Path checks cost ~10³ configuration checks each, so the lookahead
      sees endpoint collisions only; the DP oracle baseline sees every path.

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
    ``edge_rewards(i)`` gives the same prices for every move into waypoint i, for planners.

    ## Starting state
    ``reset`` draws a task from the env's ``np_random`` (seed it with ``reset(seed=…)``);
    the arm stands at the task's start configuration. With ``task="paper_transfer"`` the
    arm already stands at position 1: its first step only picks that branch, at no cost.

    ## Episode end
    Terminates after the last waypoint, on an invalid branch, and on a colliding path when
    ``terminate_on_collision``. Episodes never run longer than ``N`` steps (no truncation).
    ``info["is_success"]`` at the end: every waypoint reached, no collision, no invalid
    branch.

    ## Arguments
    ``gym.make("IKBranch/Anthropomorphic-v1", **kwargs)``; every argument is JSON-able.

    ===================== ======================= ===========================================
    argument              default                 meaning
    ===================== ======================= ===========================================
    arm                   "anthropomorphic"       a name in ``envs.kinematics.ARM_NAMES``
    scene                 "random_clutter"        "empty", "milling_cell", "random_clutter"
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
    joint_speeds          None                    per-joint speed limits (None: 1.5 rad/s, 0.5 m/s)
    collision_resolution  0.01                    path-check clearance and step (m)
    scene_seed            0                       seed of the random-clutter scene
    arm_params            None                    dict of arm parameters (``make_arm``)
    render_mode           None                    None or "rgb_array"
    width                 480                     rendered frame width (px)
    height                360                     rendered frame height (px)
    ===================== ======================= ===========================================

    ## Version history
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

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": 4}

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
        joint_speeds: list[float] | None = None,
        collision_resolution: float = 0.01,
        scene_seed: int = 0,
        arm_params: dict[str, Any] | None = None,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
    ) -> None:
        self._kwargs = {
            key: value for key, value in locals().items() if key not in ("self", "__class__")
        }
        if arm not in ARM_NAMES:
            raise ValueError(f"unknown arm {arm!r}; choose one of {', '.join(ARM_NAMES)}")
        if scene not in SCENES:
            raise ValueError(f"unknown scene {scene!r}; choose one of {', '.join(SCENES)}")
        if task not in TASKS:
            raise ValueError(f"unknown task {task!r}; choose one of {', '.join(TASKS)}")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.arm = make_arm(arm, **(arm_params or {}))
        self._generator = TASKS[task]
        self._generator.check_arm(self.arm, scene)
        self.n_waypoints = _integer(
            self._generator.default_waypoints if n_waypoints is None else n_waypoints,
            "n_waypoints", 1,
        )
        if getattr(self._generator, "fixed_waypoints", False) and (
            self.n_waypoints != self._generator.default_waypoints
        ):
            raise ValueError(
                f"task {task!r} has exactly {self._generator.default_waypoints} waypoints, "
                f"got n_waypoints={n_waypoints!r}"
            )
        lookahead = _integer(lookahead, "lookahead", 0)
        scene_seed = _integer(scene_seed, "scene_seed", 0)
        for name, value in (("collision_penalty", collision_penalty),
                            ("invalid_penalty", invalid_penalty)):
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {value}")
        if not collision_resolution > 0:
            raise ValueError(f"collision_resolution must be positive, got {collision_resolution}")
        if width < 1 or height < 1:
            raise ValueError("width and height must be positive")
        self.lookahead = lookahead
        self.cost = TransitionCost.for_arm(
            self.arm,
            travel_weight=travel_weight,
            time_weight=time_weight,
            prismatic_scale=prismatic_scale,
            joint_weights=joint_weights,
            joint_speeds=joint_speeds,
        )
        self.collision_penalty = float(collision_penalty)
        self.invalid_penalty = float(invalid_penalty)
        self.terminate_on_collision = bool(terminate_on_collision)
        self.render_mode = render_mode
        self.scene = scene

        scene_kwargs = {"seed": scene_seed} if scene == "random_clutter" else {}
        self.model = build_arm_model(self.arm, scene, **scene_kwargs)
        self.checker = CollisionChecker(
            self.model, dof=self.arm.dof, resolution=collision_resolution
        )
        self._path_cache: dict[bytes, bool] = {}
        self._endpoint_cache: dict[bytes, bool] = {}
        self._pose_cache: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._renderer = None

        lower, upper = self.arm.joint_limits[:, 0], self.arm.joint_limits[:, 1]
        self._centre, self._half_range = (upper + lower) / 2, (upper - lower) / 2
        self._travel_scale = float(self.cost.travel(lower, upper))
        #: The dearest move any branch choice can cost (travel and time between opposite
        #: joint limits); an episode that ends early pays it for every waypoint it skips.
        self.max_transition_cost = float(
            self.cost.travel_weight * self._travel_scale
            + self.cost.time_weight * self.cost.time(lower, upper)
        )
        self.observation_layout = self._layout()
        size = max(stop for _, stop in self.observation_layout.values())
        self.observation_space = spaces.Box(-1.0, 1.0, shape=(size,), dtype=np.float32)
        self.action_space = spaces.Discrete(self.arm.n_branches)

        self._q_slice = slice(*self.observation_layout["q"])
        self._travel0 = slice(*self.observation_layout["slot0/travel"])
        self._path0 = slice(*self.observation_layout["slot0/path_collision"])
        self._all_branches = np.arange(self.arm.n_branches)
        self._moves_key: tuple | None = None
        self._moves_cache: dict[str, np.ndarray] = {}

        self.task: Task | None = None
        self.candidates = self.valid = self.endpoint_collision = None
        self.q = self.arm.home.copy()
        self.index = 0

    # --------------------------------------------------------------------------- layout
    def _layout(self) -> dict[str, tuple[int, int]]:
        dof, k = self.arm.dof, self.arm.n_branches
        sizes = [("q", dof), ("progress", 1)]
        for h in range(self.lookahead + 1):
            sizes += [(f"slot{h}/present", 1), (f"slot{h}/candidates", k * dof),
                      (f"slot{h}/valid", k), (f"slot{h}/endpoint_collision", k)]
            sizes += [("slot0/travel", k), ("slot0/path_collision", k)] if h == 0 else [
                (f"slot{h}/travel", k * k)]
        layout, start = {}, 0
        for name, size in sizes:
            layout[name] = (start, start + size)
            start += size
        return layout

    # ---------------------------------------------------------------------------- API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.task = self._generator(
            self.arm, self.np_random, self.n_waypoints, self._is_free, self._is_path_free
        )
        self.candidates, self.valid, self.endpoint_collision = self._solve(self.task.poses)
        if not self.valid.any(axis=-1).all():
            raise RuntimeError("task generator produced a waypoint without a valid branch")
        self.q = np.array(self.task.start, dtype=np.float64)
        self.index = 0
        self.collided = self.invalid = False
        self._prepare_observations()
        return self._observation(), {"waypoint": 0}

    def action_masks(self) -> np.ndarray:
        """(K,) bool: the branches of the next waypoint that exist and lie inside the limits."""
        if self.task is None:
            raise RuntimeError("call reset() before action_masks()")
        if self.index >= self.task.n_waypoints:
            return np.ones(self.arm.n_branches, dtype=bool)  # episode over: any action
        return self.valid[self.index].copy()

    def step(self, action):
        if self.task is None:
            raise RuntimeError("call reset() before step()")
        if self.index >= self.task.n_waypoints:
            raise RuntimeError("the episode has ended: call reset()")
        branch = int(action)
        if branch != action or not 0 <= branch < self.arm.n_branches:
            raise ValueError(f"action must be a branch index in [0, {self.arm.n_branches})")
        waypoint = self.index
        terms = {name: value[branch].item() for name, value in self._moves().items()}
        reward = terms.pop("reward")
        terminated = terms.pop("terminal")
        if not terms["invalid"]:
            self.q = self.candidates[waypoint, branch].copy()
        self.index = self.task.n_waypoints if terminated else waypoint + 1
        self.collided |= terms["collision"]
        self.invalid |= terms["invalid"]
        info = {"waypoint": waypoint, "branch": branch, **terms}
        if terminated:
            info["is_success"] = bool(
                waypoint == self.task.n_waypoints - 1 and not self.collided and not self.invalid
            )
        return self._observation(), reward, terminated, False, info

    def edge_rewards(self, waypoint: int) -> tuple[np.ndarray, np.ndarray]:
        """Reward and termination of every move into ``waypoint``, as ``step`` pays them.

        Rows are the configurations the arm can stand in before the move: the task's start
        for waypoint 0, else the K candidates of ``waypoint − 1`` (rows of invalid ones are
        NaN); columns the K branches of ``waypoint``. Returns ``reward`` (R, K) and
        ``terminal`` (R, K) bool. Every path is collision-checked (and cached), so this is
        what an oracle with full knowledge of the task plans over.
        """
        if self.task is None:
            raise RuntimeError("call reset() before edge_rewards()")
        if not 0 <= waypoint < self.task.n_waypoints:
            raise ValueError(f"waypoint must lie in [0, {self.task.n_waypoints})")
        k = self.arm.n_branches
        if waypoint == 0:
            origins = np.asarray(self.task.start, dtype=np.float64)[None]
            usable = np.ones(1, dtype=bool)
        else:
            origins, usable = self.candidates[waypoint - 1], self.valid[waypoint - 1]
        reward = np.full((len(origins), k), np.nan)
        terminal = np.ones((len(origins), k), dtype=bool)
        for row in np.flatnonzero(usable):
            terms = self._transition_terms(origins[row][None], waypoint, np.arange(k))
            reward[row], terminal[row] = terms["reward"], terms["terminal"]
        return reward, terminal

    def _moves(self) -> dict[str, np.ndarray]:
        """``_transition_terms`` of every branch from where the arm stands into the next
        waypoint: the observation's slot-0 travel and path collisions and what ``step``
        pays, computed once per state (the same call ``edge_rewards`` makes per row)."""
        key = (self.index, self.q.tobytes())
        if self._moves_key != key:
            self._moves_cache = self._transition_terms(
                self.q[None], self.index, self._all_branches
            )
            self._moves_key = key
        return self._moves_cache

    def _transition_terms(
        self, origin: np.ndarray, waypoint: int, branches: np.ndarray
    ) -> dict[str, np.ndarray]:
        """Reward terms of moving from ``origin`` (1, dof) to ``branches`` of ``waypoint``.

        The one place a transition is priced: ``step`` and ``edge_rewards`` both call it,
        so an oracle's planned return is exactly what the env pays.
        """
        n = self.task.n_waypoints
        invalid = ~self.valid[waypoint, branches]
        targets = np.where(invalid[:, None], origin, self.candidates[waypoint, branches])
        collision = np.zeros(len(branches), dtype=bool)
        if waypoint == 0 and self.task.free_start:
            travel = duration = np.zeros(len(branches))
            collision[~invalid] = self.endpoint_collision[0, branches[~invalid]]
        else:
            travel, duration = self.cost.travel(origin, targets), self.cost.time(origin, targets)
            if (~invalid).any():
                collision[~invalid] = self._paths_collide(origin[0], targets[~invalid])
        crashed = collision & self.terminate_on_collision
        terminal = invalid | crashed | (waypoint == n - 1)
        # Waypoints an early end leaves unvisited: an invalid branch never reaches its own.
        skipped = np.where(invalid, n - waypoint, np.where(crashed, n - 1 - waypoint, 0))
        reward_travel = -self.cost.travel_weight * travel
        reward_time = -self.cost.time_weight * duration
        reward_collision = np.where(collision, -self.collision_penalty, 0.0)
        reward_invalid = np.where(invalid, -self.invalid_penalty, 0.0)
        reward_unfinished = np.where(skipped > 0, -skipped * self.max_transition_cost, 0.0)
        return {
            "reward": reward_travel + reward_time + reward_collision + reward_invalid
            + reward_unfinished,
            "terminal": terminal,
            "travel": travel,
            "time": duration,
            "collision": collision,
            "invalid": invalid,
            "reward_travel": reward_travel,
            "reward_time": reward_time,
            "reward_collision": reward_collision,
            "reward_invalid": reward_invalid,
            "reward_unfinished": reward_unfinished,
        }

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            from envs.render import SceneRenderer

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

    # ---------------------------------------------------------------- collision helpers
    def _solve(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``candidates`` (N, K, dof), ``valid`` (N, K), ``endpoint_collision`` (N, K).

        One batched IK call and one batched endpoint check for the poses not seen before
        (results are cached per pose: IK is row-wise exact, so a cached row is the row a
        fresh call would give).
        """
        poses = np.ascontiguousarray(poses, dtype=np.float64)
        cache = self._pose_cache
        keys = [pose.tobytes() for pose in poses]
        rows = [cache.get(key) for key in keys]
        missing = list({keys[i]: i for i, row in enumerate(rows) if row is None}.values())
        if missing:
            candidates, valid = self.arm.ik(poses[missing])
            endpoint = np.zeros_like(valid)
            endpoint[valid] = self._endpoints_collide(candidates[valid])
            new = {
                keys[i]: (candidates[row], valid[row], endpoint[row])
                for row, i in enumerate(missing)
            }
            if len(cache) + len(new) > POSE_CACHE_SIZE:
                cache.clear()
            cache.update(new)
            rows = [new[key] if row is None else row for key, row in zip(keys, rows, strict=True)]
        return (
            np.array([row[0] for row in rows]),
            np.array([row[1] for row in rows]),
            np.array([row[2] for row in rows]),
        )

    def _is_free(self, q: np.ndarray) -> np.ndarray:
        return ~self._endpoints_collide(q)

    def _is_path_free(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """(M,) True where the path q0[i] → q1[i] is free (through the path cache)."""
        return np.array(
            [not self._paths_collide(a, b[None])[0] for a, b in zip(q0, q1, strict=True)]
        )

    def _endpoints_collide(self, q: np.ndarray) -> np.ndarray:
        return self._cached(self._endpoint_cache, q, self.checker.collides)

    def _paths_collide(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """(M,) path collisions from q0 (dof,) to each of q1 (M, dof), cached."""
        prefix = q0.tobytes()
        return self._cached(
            self._path_cache, q1, lambda rows: self.checker.check_paths(q0, rows)[0], prefix
        )

    @staticmethod
    def _cached(cache: dict, rows: np.ndarray, compute, prefix: bytes = b"") -> np.ndarray:
        rows = np.ascontiguousarray(rows, dtype=np.float64)
        keys = [prefix + row.tobytes() for row in rows]
        found = [cache.get(key) for key in keys]
        missing = [i for i, value in enumerate(found) if value is None]
        if missing:
            values = compute(rows[missing])
            # Clearing a full cache must not lose this call's hits: fill from ``found``.
            if len(cache) + len(missing) > PATH_CACHE_SIZE:
                cache.clear()
            for i, value in zip(missing, values, strict=True):
                found[i] = cache[keys[i]] = bool(value)
        return np.array(found, dtype=bool)

    # ------------------------------------------------------------------- observation
    def _normalise(self, q: np.ndarray) -> np.ndarray:
        return (q - self._centre) / self._half_range

    def _prepare_observations(self) -> None:
        """Everything of the observation a task fixes, once per (new) task.

        ``self._templates[i]`` is the observation at ``index == i`` (i = 0 … N) but for
        the parts that depend on where the arm stands: ``q`` and slot 0's ``travel`` and
        ``path_collision``, which ``_observation`` fills in.
        """
        n, k, dof = self.task.n_waypoints, self.arm.n_branches, self.arm.dof
        valid = self.valid
        self._moves_key = None  # a new task: the cached moves belong to the old one
        # Per waypoint: present, candidates (invalid ones at the centre: 0), valid, endpoint.
        candidates = np.where(valid[..., None], self.candidates, self._centre)
        common = np.concatenate(
            [np.ones((n, 1)), self._normalise(candidates).reshape(n, k * dof), valid,
             self.endpoint_collision], axis=1,
        )
        width = common.shape[1]
        templates = np.zeros((n + 1, self.observation_space.shape[0]))
        templates[:, slice(*self.observation_layout["progress"])] = (
            np.arange(n + 1)[:, None] / n
        )
        if self.lookahead and n > 1:
            # travel[i - 1]: (K, K) from every candidate of waypoint i − 1 to every one of i.
            both = valid[:-1, :, None] & valid[1:, None, :]
            travel = np.ones((n - 1, k, k))
            travel[both] = self.cost.travel(
                self.candidates[:-1, :, None, :], self.candidates[1:, None, :, :]
            )[both] / self._travel_scale
            travel = travel.reshape(n - 1, k * k)
        for h in range(min(self.lookahead, n - 1) + 1):
            start = self.observation_layout[f"slot{h}/present"][0]
            rows = n - h  # indices 0 … n − h − 1 see waypoint index + h inside the task
            templates[:rows, start : start + width] = common[h:]
            if h:
                templates[:rows, start + width : start + width + k * k] = travel[h - 1 :]
        # Values sit inside [−1, 1] by construction; the clip only absorbs the 1e-9 slack
        # with which a branch may lie on a joint limit.
        self._templates = np.clip(templates, -1.0, 1.0).astype(np.float32)

    def _observation(self) -> np.ndarray:
        obs = self._templates[self.index].copy()
        obs[self._q_slice] = np.clip((self.q - self._centre) / self._half_range, -1.0, 1.0)
        i = self.index
        if i >= self.task.n_waypoints:
            return obs
        moves = self._moves()  # invalid branches: travel 0, collision False
        travel = moves["travel"] / self._travel_scale
        obs[self._travel0] = np.where(self.valid[i], np.minimum(travel, 1.0), 1.0)
        obs[self._path0] = moves["collision"]
        return obs

    # ---------------------------------------------------------------------- pickling
    def __getstate__(self) -> dict:
        # The task's IK solutions travel with it: the copy continues bit for bit, and
        # does not redo the IK and endpoint checks.
        return {
            "kwargs": self._kwargs,
            "rng": None if self._np_random is None else self._np_random.bit_generator.state,
            "task": self.task,
            "solutions": (self.candidates, self.valid, self.endpoint_collision),
            "q": self.q,
            "index": self.index,
            "flags": (getattr(self, "collided", False), getattr(self, "invalid", False)),
        }

    def __setstate__(self, state: dict) -> None:
        self.__init__(**state["kwargs"])
        if state["rng"] is not None:
            self._np_random = np.random.Generator(np.random.PCG64())
            self._np_random.bit_generator.state = state["rng"]
        if state["task"] is not None:
            self.task = state["task"]
            self.candidates, self.valid, self.endpoint_collision = state["solutions"]
            self._prepare_observations()
        self.q, self.index = np.array(state["q"], dtype=np.float64), state["index"]
        self.collided, self.invalid = state["flags"]
