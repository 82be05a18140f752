"""Deburring: a round burr follows the top rim of a part clamped in a fixture.

The part (``PART``) stands on a fixture plate in front of the arm (the ``deburring_cell``
scene builds the same geometry, ``envs/models/scenes.py``). Its top rim is a rectangle
with rounded corners; a burr chamfers it with its axis leaning out of the part by the
chamfer angle β (the bisector of a 90° edge is β = 45°). One episode is one pass along
the rim: ``n_waypoints`` consecutive rim samples (a sample every ``SPACING`` along the
straight edges, every ``CORNER_STEP`` of turn around a corner) from a random start, either
way round, at a random β. The whole pass is one process segment: the arm keeps its
configuration, and only the move from the start to the first rim point is an air move.

Each waypoint is the TCP's pose: its z axis along the burr into the edge (down and into
the part), its x axis the direction of travel. The burr is round: ids on this task leave
it free to turn about its axis (``tool_axis``), so the action chooses branch × spin.

A task is kept only if the arm can do it: some chain of collision-free configurations
(outside the singularity margins, where the env sets them), one per waypoint, in one
closed-form branch, each step within the env's ``max_joint_step`` (``MAX_STEP`` where it
sets none) and every path between them free (from ``START`` too) — found by a depth-first
search over the branches in the order of their travel. Otherwise the pass is drawn again
(``ROUNDS`` times at most).
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

from ikbranch_gym.envs.kinematics import Arm

from .base import FreePredicate, PathPredicate, Task, require_pose_arm, task_generator

#: The part's top rim (m, in the arm's base frame): centre, half-lengths along x and y,
#: height of the top face, corner radius; the part is ``PART_HEIGHT`` tall.
PART_CENTRE = (0.42, 0.0)
PART_HALF = (0.06, 0.08)
PART_TOP = 0.10
PART_HEIGHT = 0.06
CORNER_RADIUS = 0.012
#: Rim sampling: along the edges (m) and around the corners (rad).
SPACING = 0.02
CORNER_STEP = math.radians(15.0)
#: The chamfer angle β: the burr's axis leans out of the part by β from the vertical.
CHAMFER_RANGE = (math.radians(30.0), math.radians(50.0))
#: The step limit inside the pass (rad): the ids' ``max_joint_step``, and the search's
#: where the env sets none (an env with one searches with its own).
MAX_STEP = math.radians(30.0)
#: Where every pass starts: the KR 6 R700 above the fixture (A5 bent, tool down).
START = (0.0, -1.5707963267948966, 1.5707963267948966, 0.0, 0.7853981633974483, 0.0)
#: Passes drawn before the generator gives up.
ROUNDS = 200


@cache
def rim_samples() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rim once round, anticlockwise seen from above, from the start of the +x edge:
    points (M, 3), outward normals (M, 3) and tangents (M, 3) (horizontal unit vectors).
    Each straight edge is sampled from its start every about ``SPACING``, each corner arc
    from its start every ``CORNER_STEP`` of turn (an edge's end is its corner's start).
    Computed once, read-only (every pass is cut from it)."""
    cx, cy = PART_CENTRE
    hx, hy = PART_HALF
    r = CORNER_RADIUS
    points, normals = [], []
    for k in range(4):  # edge k has the outward normal at angle k·90°
        angle = k * math.pi / 2
        normal = np.array([math.cos(angle), math.sin(angle)])
        along = np.array([-normal[1], normal[0]])  # anticlockwise
        half_length = (hy if k % 2 == 0 else hx) - r
        middle = np.array([cx, cy]) + normal * (hx if k % 2 == 0 else hy)
        a, b = middle - along * half_length, middle + along * half_length
        count = max(1, round(float(np.linalg.norm(b - a)) / SPACING))
        for i in range(count):
            points.append((*(a + (b - a) * (i / count)), PART_TOP))
            normals.append((*normal, 0.0))
        centre = b - normal * r
        for j in range(round((math.pi / 2) / CORNER_STEP)):
            turned = angle + j * CORNER_STEP
            unit = np.array([math.cos(turned), math.sin(turned)])
            points.append((*(centre + r * unit), PART_TOP))
            normals.append((*unit, 0.0))
    normals_array = np.array(normals)
    tangents = np.cross(np.array([0.0, 0.0, 1.0]), normals_array)  # anticlockwise
    samples = (np.array(points), normals_array, tangents)
    for array in samples:
        array.flags.writeable = False
    return samples


def rim_poses(points: np.ndarray, normals: np.ndarray, tangents: np.ndarray,
              chamfer: float) -> np.ndarray:
    """(M, 4, 4) TCP poses at rim samples: z along the burr into the edge (the axis
    leaning out of the part by ``chamfer``), x the direction of travel ``tangents``."""
    up = np.array([0.0, 0.0, 1.0])
    axis = math.sin(chamfer) * normals + math.cos(chamfer) * up  # from the edge up the burr
    z = -axis
    x = tangents
    y = np.cross(z, x)
    poses = np.zeros((len(points), 4, 4))
    poses[:, :3, 0], poses[:, :3, 1], poses[:, :3, 2] = x, y, z
    poses[:, :3, 3] = points
    poses[:, 3, 3] = 1.0
    return poses


def _pass(rng: np.random.Generator, count: int) -> np.ndarray:
    """One random pass: ``count`` consecutive rim samples from a random start, either way
    round, at a random chamfer angle."""
    points, normals, tangents = rim_samples()
    if count > len(points):
        raise ValueError(f"deburring: at most {len(points)} waypoints (the rim once round), "
                         f"got {count}")
    start = int(rng.integers(len(points)))
    way = 1 if rng.random() < 0.5 else -1
    index = (start + way * np.arange(count)) % len(points)
    chamfer = float(rng.uniform(*CHAMFER_RANGE))
    return rim_poses(points[index], normals[index], way * tangents[index], chamfer)


def followable_chain(arm: Arm, start: np.ndarray, poses: np.ndarray, is_free: FreePredicate,
                     is_path_free: PathPredicate, limit: float = MAX_STEP,
                     budget: int = 400) -> np.ndarray | None:
    """(N, dof) collision-free configurations of ``poses``, one closed-form branch for all,
    each step within ``limit`` on every revolute joint and every path free, the first
    reached from ``start`` along a free path; or None if a depth-first search (the
    candidates nearest first, at most ``budget`` path checks) finds none."""
    candidates, valid = arm.ik(poses)
    closed = np.asarray(arm.branch_closed_form)
    revolute = np.asarray(arm.revolute_mask)
    free = np.zeros_like(valid)
    rows = np.flatnonzero(valid.ravel())
    if len(rows):
        free.ravel()[rows] = is_free(candidates.reshape(-1, arm.dof)[rows])
    if not free.any(axis=1).all():  # a waypoint no chain can reach: no search needed
        return None
    checks = [0]

    def extend(i: int, q: np.ndarray, configuration: int, chain: list) -> list | None:
        if i == len(poses):
            return chain
        options = np.flatnonzero(free[i] & ((closed == configuration) if i else True))
        if i:
            steps = np.abs(candidates[i, options] - q)[:, revolute].max(axis=1)
            options = options[steps <= limit]
        order = options[np.argsort(np.abs(candidates[i, options] - q).sum(axis=1),
                                   kind="stable")]
        for k in order:
            if checks[0] >= budget:
                return None
            checks[0] += 1
            target = candidates[i, k]
            if not is_path_free(q[None], target[None])[0]:
                continue
            found = extend(i + 1, target, int(closed[k]), [*chain, target])
            if found is not None:
                return found
        return None

    chain = extend(0, np.asarray(start, dtype=np.float64), -1, [])
    return None if chain is None else np.array(chain)


def _require_cell(arm: Arm, scene: str) -> None:
    require_pose_arm(arm, scene)
    if scene != "deburring_cell":
        raise ValueError(f"the deburring task needs scene='deburring_cell', not {scene!r}")


@task_generator(default_waypoints=12, check_arm=_require_cell, step_limited=True)
def deburring(
    arm: Arm,
    rng: np.random.Generator,
    n_waypoints: int,
    is_free: FreePredicate,
    is_path_free: PathPredicate,
    max_step: float = MAX_STEP,
) -> Task:
    """One pass of the burr along the part's rim (module docstring), from ``START``, that
    the arm can follow with steps of at most ``max_step`` (rad)."""
    start = np.array(START)
    for _ in range(ROUNDS):
        poses = _pass(rng, n_waypoints)
        if followable_chain(arm, start, poses, is_free, is_path_free,
                            limit=max_step) is not None:
            return Task(start=start, poses=poses,
                        segments=np.zeros(n_waypoints, dtype=np.int64))
    raise RuntimeError(f"{arm.name}: no deburring pass of {n_waypoints} waypoints the arm "
                       f"can follow with joint steps of at most {math.degrees(max_step):.4g}° "
                       f"in {ROUNDS} draws")
