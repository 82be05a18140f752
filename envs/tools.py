"""A tool held by the arm: its solids (part of the collision model) and its TCP.

A tool is given as a JSON-able dict (the env's ``tool=`` argument, ``ikbranch plan
--tool``). One solid::

    {"shape": "cylinder", "size": [0.025, 0.35],         # radius, length (m)
     "offset": {"pos": [0, 0, 0], "rpy": [0, 0, 0]},       # the solid in the fk frame
     "tcp": {"pos": [0, 0, 0.35], "quat": [1, 0, 0, 0]}}   # the TCP in the fk frame

or several (a gripper and the tool it holds, a tool changer and a spindle, …), each with
the keys of one solid, and one TCP for the whole tool::

    {"parts": [{"shape": "box", "size": [0.1, 0.08, 0.2]},               # the gripper
               {"shape": "cylinder", "size": [0.025, 0.35],              # the held tool
                "offset": {"pos": [0, 0, 0.2], "rpy": [-1.5707963267948966, 0, 0]}}],
     "tcp": {"pos": [0, 0, 0.2]}}

- ``shape``: ``"cylinder"`` (``size`` radius, length: along the solid frame's +z from its
  origin), ``"box"`` (``size``: full lengths x, y, z, its centre at ``length_z / 2`` along
  +z, so it too starts at the frame's origin), or ``"mesh"`` (``mesh``: an STL/OBJ file in
  metres, in the solid frame; MuJoCo collides it as its convex hull).
- ``offset`` (per solid) and ``tcp``: poses relative to the arm's ``fk`` frame (the flange
  of the industrial arms, the wrist centre of the papers' arms), each ``{"pos": …}`` with
  ``"quat"`` (w, x, y, z; unit within 1e-6) or ``"rpy"`` (rad, Rz·Ry·Rx); default identity.
- ``parts``: a non-empty list of solids; the one-solid form is the one-part tool. Every
  part collides with the scene and with the arm's links (but the two wrist bodies it is
  mounted through); the parts of one tool never collide with each other. In the MuJoCo
  model part 0 is the geom ``tool``, part i the geom ``tool_<i>`` (``tool_1``, …).

With a tool, waypoint poses target the TCP: the fk frame must stand at
``pose · inv(tcp)``, which :meth:`Tool.flange_poses` returns.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Unit quaternions are accepted this close to norm 1 (never normalised beyond it).
QUATERNION_TOL = 1e-6
SHAPES = ("cylinder", "box", "mesh")
#: The keys of one solid (a one-solid tool adds ``tcp``; a part has exactly these).
SOLID_KEYS = ("shape", "size", "mesh", "offset")


#: No tool frame lies farther than this (m) from the flange: a larger one was most likely
#: written in millimetres.
MAX_TOOL_LENGTH = 5.0


def _frame(spec: Any, label: str) -> np.ndarray:
    """(4, 4) from ``{"pos": [3], "quat": [4] | "rpy": [3]}`` (None: identity)."""
    pose = np.eye(4)
    if spec is None:
        return pose
    if not isinstance(spec, dict) or set(spec) - {"pos", "quat", "rpy"}:
        raise ValueError(f"{label} must be a dict with 'pos' and 'quat' or 'rpy', got "
                         f"{spec!r}")
    if "quat" in spec and "rpy" in spec:
        raise ValueError(f"{label}: give 'quat' or 'rpy', not both")
    if "pos" in spec:
        pose[:3, 3] = _numbers(spec["pos"], 3, f"{label}.pos")
        if np.abs(pose[:3, 3]).max() > MAX_TOOL_LENGTH:
            raise ValueError(f"{label}.pos {list(spec['pos'])} lies more than "
                             f"{MAX_TOOL_LENGTH:g} m from the flange: is it in millimetres? "
                             "Tool files give metres")
    if "quat" in spec:
        w, x, y, z = _numbers(spec["quat"], 4, f"{label}.quat")
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        if not abs(norm - 1.0) <= QUATERNION_TOL:
            raise ValueError(f"{label}.quat has norm {norm!r}, not 1 within "
                             f"{QUATERNION_TOL:g}")
        s = 2.0 / (norm * norm)
        pose[:3, :3] = [
            [1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)],
            [s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)],
            [s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)],
        ]
    if "rpy" in spec:
        roll, pitch, yaw = _numbers(spec["rpy"], 3, f"{label}.rpy")
        cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(yaw), math.sin(yaw)
        pose[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                        [-sp, cp * sr, cp * cr]]
    return pose


def _numbers(value: Any, count: int, label: str) -> tuple[float, ...]:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{label} must be {count} numbers, got {value!r}") from None
    if array.shape != (count,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{label} must be {count} finite numbers, got {value!r}")
    return tuple(float(v) for v in array)


@dataclass(frozen=True, eq=False)
class ToolPart:
    """One solid of a tool: ``shape``, ``size``, ``mesh`` and its ``offset`` frame (4, 4)
    in the fk frame (module docstring)."""

    shape: str
    size: tuple[float, ...]
    offset: np.ndarray
    mesh: Path | None = None

    @classmethod
    def from_spec(cls, spec: Any, label: str = "tool") -> ToolPart:
        """``spec``: the keys of one solid; errors start with ``label``."""
        if not isinstance(spec, dict):
            raise ValueError(f"{label} must be a dict with {', '.join(map(repr, SOLID_KEYS))}, "
                             f"got {spec!r}")
        shape = spec.get("shape")
        if shape not in SHAPES:
            raise ValueError(f"{label} shape must be one of {', '.join(SHAPES)}, got {shape!r}")
        mesh = None
        if shape == "mesh":
            if "mesh" not in spec:
                raise ValueError(f"{label} shape 'mesh' needs 'mesh': a path to an STL/OBJ "
                                 f"file")
            if not isinstance(spec["mesh"], str | os.PathLike):
                raise ValueError(f"{label} mesh must be the path of an STL/OBJ file, got "
                                 f"{spec['mesh']!r}")
            mesh = Path(spec["mesh"])
            if not mesh.is_file():
                raise ValueError(f"{label} mesh {mesh}: no such file")
            size: tuple[float, ...] = ()
        else:
            count = 2 if shape == "cylinder" else 3
            size = _numbers(spec.get("size"), count, f"{label} size")
            if min(size) <= 0:
                raise ValueError(f"{label} size must be positive, got {list(size)}")
            if max(size) > MAX_TOOL_LENGTH:
                raise ValueError(f"{label} size {list(size)} is more than "
                                 f"{MAX_TOOL_LENGTH:g} m: is it in millimetres? Tool files "
                                 "give metres")
        return cls(shape, size, _frame(spec.get("offset"), f"{label} offset"), mesh)


@dataclass(frozen=True, eq=False)
class Tool:
    """A parsed tool (module docstring): its ``parts`` (:class:`ToolPart`, at least one)
    and the ``tcp`` frame (4, 4) in the fk frame. ``shape``, ``size``, ``offset`` and
    ``mesh`` are part 0's (the whole solid of a one-solid tool)."""

    shape: str
    size: tuple[float, ...]
    offset: np.ndarray
    tcp: np.ndarray
    mesh: Path | None = None
    spec: dict = field(default_factory=dict)
    parts: tuple[ToolPart, ...] = ()

    def __post_init__(self) -> None:
        if not self.parts:  # a one-solid tool: its one part is the solid
            object.__setattr__(self, "parts",
                               (ToolPart(self.shape, self.size, self.offset, self.mesh),))

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> Tool:
        """``ValueError`` naming the field for anything malformed."""
        if not isinstance(spec, dict):
            raise ValueError(f"tool must be a dict, got {spec!r}")
        if "parts" not in spec:
            unknown = set(spec) - {*SOLID_KEYS, "tcp"}
            if unknown:
                raise ValueError(f"tool: unknown keys {sorted(unknown)}")
            part = ToolPart.from_spec(spec, "tool")
            return cls(part.shape, part.size, part.offset, _frame(spec.get("tcp"), "tool tcp"),
                       part.mesh, dict(spec), (part,))
        solid = sorted(set(spec) & set(SOLID_KEYS))
        if solid:
            raise ValueError(f"tool: give 'parts' or the keys of one solid, not both (also "
                             f"got {solid}; put them into a part)")
        unknown = set(spec) - {"parts", "tcp"}
        if unknown:
            raise ValueError(f"tool: unknown keys {sorted(unknown)}")
        items = spec["parts"]
        if not isinstance(items, list | tuple) or not items:
            raise ValueError(f"tool parts must be a non-empty list of solids, got {items!r}")
        parts = []
        for index, item in enumerate(items):
            label = f"tool parts[{index}]"
            if isinstance(item, dict):
                unknown = set(item) - set(SOLID_KEYS)
                if unknown:
                    hint = " (the tcp is the whole tool's, not a part's)" if "tcp" in unknown \
                        else ""
                    raise ValueError(f"{label}: unknown keys {sorted(unknown)}{hint}")
            parts.append(ToolPart.from_spec(item, label))
        first = parts[0]
        return cls(first.shape, first.size, first.offset, _frame(spec.get("tcp"), "tool tcp"),
                   first.mesh, dict(spec), tuple(parts))

    def flange_poses(self, poses: np.ndarray) -> np.ndarray:
        """Where the fk frame must stand (…, 4, 4) for the TCP to be at ``poses``."""
        inverse = np.eye(4)
        inverse[:3, :3] = self.tcp[:3, :3].T
        inverse[:3, 3] = -(self.tcp[:3, :3].T @ self.tcp[:3, 3])
        return np.asarray(poses, dtype=np.float64) @ inverse

    def tcp_poses(self, flange: np.ndarray) -> np.ndarray:
        """The TCP (…, 4, 4) when the fk frame stands at ``flange``."""
        return np.asarray(flange, dtype=np.float64) @ self.tcp
