"""A tool held by the arm: its solid (part of the collision model) and its TCP.

A tool is given as a JSON-able dict (the env's ``tool=`` argument, ``ikbranch plan
--tool``)::

    {"shape": "cylinder", "size": [0.025, 0.35],         # radius, length (m)
     "offset": {"pos": [0, 0, 0], "rpy": [0, 0, 0]},       # the solid in the fk frame
     "tcp": {"pos": [0, 0, 0.35], "quat": [1, 0, 0, 0]}}   # the TCP in the fk frame

- ``shape``: ``"cylinder"`` (``size`` radius, length: along the solid frame's +z from its
  origin), ``"box"`` (``size``: full lengths x, y, z, its centre at ``length_z / 2`` along
  +z, so it too starts at the frame's origin), or ``"mesh"`` (``mesh``: an STL/OBJ file in
  metres, in the solid frame; MuJoCo collides it as its convex hull).
- ``offset`` and ``tcp``: poses relative to the arm's ``fk`` frame (the flange of the
  industrial arms, the wrist centre of the papers' arms), each ``{"pos": …}`` with
  ``"quat"`` (w, x, y, z; unit within 1e-6) or ``"rpy"`` (rad, Rz·Ry·Rx); default identity.

With a tool, waypoint poses target the TCP: the fk frame must stand at
``pose · inv(tcp)``, which :meth:`Tool.flange_poses` returns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Unit quaternions are accepted this close to norm 1 (never normalised beyond it).
QUATERNION_TOL = 1e-6
SHAPES = ("cylinder", "box", "mesh")


def _frame(spec: Any, name: str) -> np.ndarray:
    """(4, 4) from ``{"pos": [3], "quat": [4] | "rpy": [3]}`` (None: identity)."""
    pose = np.eye(4)
    if spec is None:
        return pose
    if not isinstance(spec, dict) or set(spec) - {"pos", "quat", "rpy"}:
        raise ValueError(f"tool {name} must be a dict with 'pos' and 'quat' or 'rpy', got "
                         f"{spec!r}")
    if "quat" in spec and "rpy" in spec:
        raise ValueError(f"tool {name}: give 'quat' or 'rpy', not both")
    if "pos" in spec:
        pose[:3, 3] = _numbers(spec["pos"], 3, f"{name}.pos")
    if "quat" in spec:
        w, x, y, z = _numbers(spec["quat"], 4, f"{name}.quat")
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        if not abs(norm - 1.0) <= QUATERNION_TOL:
            raise ValueError(f"tool {name}.quat has norm {norm!r}, not 1 within "
                             f"{QUATERNION_TOL:g}")
        s = 2.0 / (norm * norm)
        pose[:3, :3] = [
            [1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)],
            [s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)],
            [s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)],
        ]
    if "rpy" in spec:
        roll, pitch, yaw = _numbers(spec["rpy"], 3, f"{name}.rpy")
        cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(yaw), math.sin(yaw)
        pose[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                        [-sp, cp * sr, cp * cr]]
    return pose


def _numbers(value, count: int, name: str) -> tuple[float, ...]:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"tool {name} must be {count} numbers, got {value!r}") from None
    if array.shape != (count,) or not np.all(np.isfinite(array)):
        raise ValueError(f"tool {name} must be {count} finite numbers, got {value!r}")
    return tuple(float(v) for v in array)


@dataclass(frozen=True, eq=False)
class Tool:
    """A parsed tool (module docstring): ``shape``, ``size``, ``mesh``, and the ``offset``
    and ``tcp`` frames (4, 4) in the fk frame."""

    shape: str
    size: tuple[float, ...]
    offset: np.ndarray
    tcp: np.ndarray
    mesh: Path | None = None
    spec: dict = field(default_factory=dict)

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> Tool:
        """``ValueError`` naming the field for anything malformed."""
        if not isinstance(spec, dict):
            raise ValueError(f"tool must be a dict, got {spec!r}")
        unknown = set(spec) - {"shape", "size", "mesh", "offset", "tcp"}
        if unknown:
            raise ValueError(f"tool: unknown keys {sorted(unknown)}")
        shape = spec.get("shape")
        if shape not in SHAPES:
            raise ValueError(f"tool shape must be one of {', '.join(SHAPES)}, got {shape!r}")
        mesh = None
        if shape == "mesh":
            if "mesh" not in spec:
                raise ValueError("tool shape 'mesh' needs 'mesh': a path to an STL/OBJ file")
            mesh = Path(spec["mesh"])
            if not mesh.is_file():
                raise ValueError(f"tool mesh {mesh}: no such file")
            size: tuple[float, ...] = ()
        else:
            count = 2 if shape == "cylinder" else 3
            size = _numbers(spec.get("size"), count, "size")
            if min(size) <= 0:
                raise ValueError(f"tool size must be positive, got {list(size)}")
        return cls(shape, size, _frame(spec.get("offset"), "offset"),
                   _frame(spec.get("tcp"), "tcp"), mesh, dict(spec))

    def flange_poses(self, poses: np.ndarray) -> np.ndarray:
        """Where the fk frame must stand (…, 4, 4) for the TCP to be at ``poses``."""
        inverse = np.eye(4)
        inverse[:3, :3] = self.tcp[:3, :3].T
        inverse[:3, 3] = -(self.tcp[:3, :3].T @ self.tcp[:3, 3])
        return np.asarray(poses, dtype=np.float64) @ inverse

    def tcp_poses(self, flange: np.ndarray) -> np.ndarray:
        """The TCP (…, 4, 4) when the fk frame stands at ``flange``."""
        return np.asarray(flange, dtype=np.float64) @ self.tcp
