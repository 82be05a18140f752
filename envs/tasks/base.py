"""The task record and the generator protocol."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, cast

import numpy as np

from ikbranch_gym.envs.kinematics import Arm


class FreePredicate(Protocol):
    """Collision predicate the env hands to generators: (M, dof) -> (M,) bool, True =
    free (and outside the singularity margins, where the env sets them: the ladder leaves
    every branch inside them out, ``MovePricer.is_workable``). ``need``: the caller uses
    only the first ``need`` free rows, so rows after the ``need``-th free one may come
    back False without being checked (the env stops there)."""

    def __call__(self, q: np.ndarray, need: int | None = None) -> np.ndarray: ...

    # Functions and bound methods are: a generator may remember answers per predicate.
    def __hash__(self) -> int: ...


#: Path predicate: q0 (M, dof), q1 (M, dof) -> (M,) bool, True where the linear joint-space
#: path q0 → q1 is collision-free (the env's path check, the one ``step`` charges).
PathPredicate = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class Task:
    """One episode's job.

    ``start`` (dof,): the configuration before the first step. ``poses`` (N, 4, 4): the
    waypoints in order. ``free_start``: the arm already stands *at* waypoint 0 and its
    first step only chooses that waypoint's branch, at no motion cost (the paper's transfer
    starts in the rack); otherwise it moves there from ``start``. ``segments`` (N,) int:
    the process segment of each waypoint (``envs/process.py``; None: one segment), used
    when the env keeps process continuity.
    """

    start: np.ndarray
    poses: np.ndarray
    free_start: bool = False
    segments: np.ndarray | None = None

    @property
    def n_waypoints(self) -> int:
        return len(self.poses)


class TaskGenerator(Protocol):
    #: Waypoints when the env's ``n_waypoints`` is None.
    default_waypoints: int
    #: The task has exactly ``default_waypoints`` waypoints (the env rejects another count).
    fixed_waypoints: bool
    #: Its poses come from a finite set, so the same moves recur from task to task (a
    #: vector env then checks paths through each sub-env's path cache).
    finite_poses: bool
    #: It draws a process segment only where the arm can follow it within a joint step
    #: limit, which it takes as ``max_step`` (rad): the env passes its ``max_joint_step``.
    step_limited: bool

    def __call__(
        self,
        arm: Arm,
        rng: np.random.Generator,
        n_waypoints: int,
        is_free: FreePredicate,
        is_path_free: PathPredicate,
    ) -> Task: ...

    def check_arm(self, arm: Arm, scene: str) -> None:
        """``ValueError`` if the generator cannot serve this arm in this scene."""


#: A generator function before ``task_generator`` gives it its attributes.
GeneratorFunction = Callable[
    [Arm, np.random.Generator, int, FreePredicate, PathPredicate], Task
]


def task_generator(
    default_waypoints: int,
    check_arm: Callable[[Arm, str], None] | None = None,
    fixed_waypoints: bool = False,
    finite_poses: bool = False,
    step_limited: bool = False,
) -> Callable[[GeneratorFunction], TaskGenerator]:
    """Decorate a generator function with its default length, applicability check and
    the attributes of :class:`TaskGenerator`."""

    def decorate(function: GeneratorFunction) -> TaskGenerator:
        # The function object itself becomes the generator: with the attributes set
        # below it has everything ``TaskGenerator`` asks for.
        generator = cast(TaskGenerator, function)
        generator.default_waypoints = default_waypoints
        generator.fixed_waypoints = fixed_waypoints
        generator.finite_poses = finite_poses
        generator.step_limited = step_limited
        # The protocol spells ``check_arm`` as a method (``FileTask``'s is a staticmethod);
        # here it is an attribute holding a function, called the same way. mypy refuses to
        # assign to a method, hence the ignore.
        generator.check_arm = check_arm or (  # type: ignore[method-assign, assignment]
            lambda arm, scene: None
        )
        return generator

    return decorate


#: Rounds of draws ``sample_free_configurations`` makes before it gives up (each at least
#: 8 configurations: 16,000 or more in all). Where free configurations are found sooner
#: the rounds after are never drawn, so the number changes no task that was found; it
#: only decides how scarce free space may be before a clutter is refused: an UR5e's
#: drawn arm among a dense clutter leaves as little as 7 % of its configurations free
#: (the least of 300 training scenes), and 50 rounds once fell short in training.
SAMPLE_ROUNDS = 2000


def sample_free_configurations(
    arm: Arm, rng: np.random.Generator, count: int, is_free: FreePredicate,
    max_rounds: int = SAMPLE_ROUNDS,
) -> np.ndarray:
    """``count`` configurations drawn uniformly inside the limits and collision-free."""
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    found: list[np.ndarray] = []
    have = 0
    for _ in range(max_rounds):
        draw = rng.uniform(lower, upper, size=(max(2 * (count - have), 8), arm.dof))
        free = draw[is_free(draw, need=count - have)][: count - have]
        found.append(free)
        have += len(free)
        if have >= count:
            return np.concatenate(found)[:count]
    raise RuntimeError(
        f"{arm.name}: found only {have} of {count} collision-free configurations in "
        f"{max_rounds} rounds; the scene leaves too little free space"
    )


class RangedArm:
    """``arm`` whose random draws stay inside ``joint_range`` (dof, 2) (rad, m): its
    ``joint_limits`` for the task generators that draw configurations inside them;
    everything else (``fk``, the branches, the real limits of the moves) is the arm's
    own."""

    def __init__(self, arm: Arm, joint_range: np.ndarray) -> None:
        self.arm = arm
        self.joint_limits = joint_range

    def __getattr__(self, name: str) -> Any:
        return getattr(self.arm, name)


def require_pose_arm(arm: Arm, scene: str) -> None:
    if arm.target != "pose" or arm.dof != 6 or arm.relative:
        raise ValueError(f"this task needs a six-DOF single arm, not {arm.name!r}")
