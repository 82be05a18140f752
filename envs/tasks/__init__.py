"""Waypoint-sequence generators: what the arm has to do in one episode.

A generator draws a :class:`Task` from the env's ``np_random`` only. Tasks never touch the
simulator: where a generator must avoid obstacles it asks the ``is_free`` predicate the env
hands it (configurations (M, dof) -> (M,) bool, True where collision-free).

================== ============================ ==========================================
name               arms                         waypoints
================== ============================ ==========================================
``random``         every arm                    FK of random collision-free configurations
``helix``          six-DOF pose arms            a helix, gripper on its Frenet frame (eq. 7)
``circle``         six-DOF pose arms            a horizontal circle, Frenet frame (†)
``line``           six-DOF pose arms            a straight line, constant orientation
``relative_motion`` two-arm systems             a relative-motion profile M34(t)
``relative_motion_free`` two-arm systems        the same, its sweep a collision-free path
``tool_changes``   anthropomorphic, milling cell above slot, slot, above slot, spindle …
``paper_transfer`` anthropomorphic              the paper's positions 1 → 2
``screwing``       six-DOF pose arms            the tool turning about its axis, 480–960°
``deburring``      six-DOF pose arms, deburring_cell  a burr along the part's rim, one segment
``file``           six-DOF pose arms            the poses of a waypoint file (``task_file``)
================== ============================ ==========================================

(†) A full Frenet circle turns the gripper once about the vertical: the anthropomorphic
arm follows it; the cartesian, cylindrical and spherical arms' wrist bend range (±135°)
cannot at the default 8 waypoints, and ``reset`` then fails with a ``RuntimeError`` after
200 placements (3 waypoints work).

Waypoint files (CSV/JSON, ``read_waypoints``/``write_waypoints``) are read by
:mod:`envs.tasks.waypoint_file` (``docs/files.md``).
"""

from __future__ import annotations

from .base import Task, TaskGenerator
from .deburring import deburring
from .paths import circle, helix, line
from .random_reachable import random_reachable
from .relative_motion import relative_motion, relative_motion_free
from .screwing import screwing
from .tool_transfer import paper_transfer, tool_changes
from .waypoint_file import WaypointFile, WaypointFileError, read_waypoints, write_waypoints

TASKS: dict[str, TaskGenerator | None] = {
    "random": random_reachable,
    "helix": helix,
    "circle": circle,
    "line": line,
    "relative_motion": relative_motion,
    "relative_motion_free": relative_motion_free,
    "tool_changes": tool_changes,
    "paper_transfer": paper_transfer,
    "screwing": screwing,
    "deburring": deburring,
    # The env builds a FileTask from ``task_file=PATH`` (envs/tasks/file_task.py).
    "file": None,
}

__all__ = [
    "TASKS",
    "Task",
    "TaskGenerator",
    "WaypointFile",
    "WaypointFileError",
    "read_waypoints",
    "write_waypoints",
]
