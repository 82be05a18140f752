"""``task="file"``: one fixed task, read from a waypoint file (``envs/tasks/waypoint_file.py``)."""

from __future__ import annotations

import math

import numpy as np

from ikbranch_gym.envs.kinematics import Arm

from .base import FreePredicate, PathPredicate, Task
from .waypoint_file import WaypointFile


class FileTask:
    """The waypoints of ``waypoints`` (``poses`` (N, 4, 4), in the task frame: the cell,
    of the TCP; ``envs/task_frame.py``) every episode, from ``start`` (dof,), or, with
    ``start`` None, from a free choice of the first waypoint's branch at no cost (as the
    paper's transfer starts in the rack). ``segments`` (N,) int: each waypoint's process
    segment (default: the file's own, ``WaypointFile.segments``)."""

    fixed_waypoints = True
    finite_poses = True
    #: The file's waypoints are the job: a segment the arm cannot follow within the
    #: env's step limit is a ``ValueError`` naming where it breaks, not a redraw.
    step_limited = False

    def __init__(self, waypoints: WaypointFile, poses: np.ndarray,
                 start: np.ndarray | None, segments: np.ndarray | None = None,
                 rows: np.ndarray | None = None) -> None:
        self.waypoints = waypoints
        #: The file's data rows the poses are (all of them, unless some were skipped).
        self.rows = np.arange(len(poses)) if rows is None else np.asarray(rows)
        self.poses = np.array(poses, dtype=np.float64)
        self.poses.flags.writeable = False
        self.start = None if start is None else np.array(start, dtype=np.float64)
        self.default_waypoints = len(self.poses)
        self.segments = np.array(waypoints.segments if segments is None else segments,
                                 dtype=np.int64)
        if self.segments.shape != (len(self.poses),):
            raise ValueError(f"{len(self.segments)} segment indices for {len(self.poses)} "
                             "waypoints")
        self.segments.flags.writeable = False

    def __call__(self, arm: Arm, rng: np.random.Generator, n_waypoints: int,
                 is_free: FreePredicate, is_path_free: PathPredicate) -> Task:
        if self.start is None:
            return Task(start=arm.home.copy(), poses=self.poses, free_start=True,
                        segments=self.segments)
        return Task(start=self.start.copy(), poses=self.poses, segments=self.segments)

    @staticmethod
    def check_arm(arm: Arm, scene: str) -> None:
        if arm.target != "pose":
            raise ValueError(f"waypoint files give poses; {arm.name} is position-only")

    def unreachable(self, arm: Arm) -> list[str]:
        """Per row that no branch of ``arm`` (seen from the task frame) reaches, the
        reason: out of reach, or every branch outside the joint limits."""
        return [problem for _, problem in self.unreachable_rows(arm)]

    def unreachable_rows(self, arm: Arm) -> list[tuple[int, str]]:
        """(waypoint, reason) of every waypoint no branch of ``arm`` reaches."""
        _, valid = arm.ik(self.poses)
        rows = np.flatnonzero(~valid.any(axis=-1))
        if not len(rows):
            return []
        exists = arm.reaches(self.poses[rows])
        return [(int(row), str(self.waypoints.row_error(
            int(self.rows[row]), _outside_limits(arm, self.poses[row]) if inside else
            _out_of_reach(self.poses[row])))) for row, inside in zip(rows, exists, strict=True)]

    def keeping(self, waypoints: np.ndarray) -> FileTask:
        """This task with only ``waypoints`` (indices, in order): the rest skipped."""
        keep = np.asarray(waypoints, dtype=np.int64)
        return FileTask(self.waypoints, self.poses[keep], self.start, self.segments[keep],
                        self.rows[keep])


#: A waypoint farther than this (m) from the task frame's origin is no arm's: its file was
#: most likely written in millimetres.
MM_HINT_DISTANCE = 10.0


def _out_of_reach(pose: np.ndarray) -> str:
    problem = "out of reach (no branch exists)"
    position = pose[:3, 3]
    if np.abs(position).max() > MM_HINT_DISTANCE:
        shown = ", ".join(f"{v:g}" for v in position)
        problem += (f"; its position ({shown}) lies more than {MM_HINT_DISTANCE:g} m away: "
                    "is the file in millimetres? Waypoint files give metres (only the "
                    "four-point format is in mm)")
    return problem


def _outside_limits(arm: Arm, pose: np.ndarray) -> str:
    """The problem of a pose some branch reaches outside the joint limits only: which
    joint of the nearest branch passes which limit, by how much."""
    problem = "every branch lies outside the joint limits"
    found = arm.limit_overshoot(pose)
    if found is None:
        return problem
    branch, joint, value, bound = found
    name, label = arm.joint_names[joint], arm.closed_form_labels[branch]
    if arm.joint_types[joint] == "prismatic":
        unit, scale = " mm", 1000.0
    else:
        unit, scale = "°", math.degrees(1.0)
    return (f"{problem}: the nearest, {label}, needs {name} = {value * scale:.2f}{unit}, "
            f"{abs(value - bound) * scale:.2f}{unit} beyond its limit {bound * scale:.2f}{unit}")
