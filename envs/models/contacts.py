"""Allowed contacts and clearance: the collision pairs a job may touch, and how far the
others stay apart.

A job may touch on purpose: a deburring burr on the part, a gripper's fingers on the
piece it holds. :func:`allow_contacts` takes such pairs out of the compiled model's
collision pairs (an allowed collision matrix): every collision geom keeps colliding with
every other, only the named pairs are left out. MuJoCo can exclude body pairs only, so
the pairs are left out by contype/conaffinity bits, the rule MuJoCo (and
``collision.candidate_pairs``, which the compiled filter checks) apply to every geom pair:
a geom of an allowed pair gets a bit of its own as contype, and a conaffinity holding
every bit but those of its allowed partners; every other collision geom keeps contype 1
and accepts every bit.

:func:`clearance` measures, at a configuration, the least distance between the geoms of
every pair still checked, and which pair it is.
"""

from __future__ import annotations

import fnmatch
from collections.abc import Sequence

import mujoco
import numpy as np

from .collision import candidate_pairs

#: The most geoms allowed pairs may name (one contype bit each, bit 0 being everyone's).
MAX_ALLOWED_GEOMS = 31


def _collision_geoms(model: mujoco.MjModel) -> dict[str, int]:
    return {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or f"geom{g}": int(g)
            for g in np.flatnonzero((model.geom_contype | model.geom_conaffinity) != 0)}


def allow_contacts(model: mujoco.MjModel,
                   pairs: Sequence[Sequence[str]]) -> list[tuple[str, str]]:
    """Leave the geom pairs ``pairs`` (each two ``fnmatch`` patterns of collision geom
    names, e.g. ``["tool*", "scene/part*"]``) out of ``model``'s collision pairs, in
    place. Returns the geom-name pairs left out. ``ValueError`` for a pattern that names no
    collision geom (listing them), or more than ``MAX_ALLOWED_GEOMS`` geoms."""
    geoms = _collision_geoms(model)
    allowed: set[tuple[int, int]] = set()
    for pair in pairs:
        if len(pair) != 2:
            raise ValueError(f"an allowed contact is two geom names (patterns), got {pair!r}")
        sides = []
        for pattern in pair:
            found = [g for name, g in geoms.items() if fnmatch.fnmatchcase(name, pattern)]
            if not found:
                raise ValueError(f"allowed contact {pattern!r} names no collision geom; the "
                                 f"model's are {', '.join(sorted(geoms))}")
            sides.append(found)
        allowed |= {(min(a, b), max(a, b)) for a in sides[0] for b in sides[1] if a != b}
    special = sorted({g for pair in allowed for g in pair})
    if len(special) > MAX_ALLOWED_GEOMS:
        raise ValueError(f"allowed contacts name {len(special)} geoms; at most "
                         f"{MAX_ALLOWED_GEOMS}")
    bits = {g: 1 << (i + 1) for i, g in enumerate(special)}
    every = 1 | sum(bits.values())
    for g in geoms.values():
        model.geom_contype[g] = bits.get(g, 1)
        partners = {b for a, b in allowed if a == g} | {a for a, b in allowed if b == g}
        model.geom_conaffinity[g] = every & ~sum(bits[p] for p in partners)
    names = {g: name for name, g in geoms.items()}
    return sorted((names[a], names[b]) for a, b in allowed)


def clearance(model: mujoco.MjModel, data: mujoco.MjData, q: np.ndarray,
              pairs: np.ndarray | None = None, distmax: float = 1.0
              ) -> tuple[float, tuple[str, str]]:
    """The least distance (m) between the two geoms of any pair ``mj_collision`` may test
    (``pairs``, default ``collision.candidate_pairs``: allowed contacts left out) with the
    first joints at ``q`` (the rest at ``qpos0``), and the pair; ``distmax`` and ("", "")
    if every pair is farther."""
    data.qpos[:] = model.qpos0
    data.qpos[: len(q)] = q
    mujoco.mj_kinematics(model, data)
    best, found = distmax, (-1, -1)
    fromto = np.zeros(6)
    for g1, g2 in candidate_pairs(model) if pairs is None else pairs:
        distance = mujoco.mj_geomDistance(model, data, int(g1), int(g2), best, fromto)
        if distance < best:
            best, found = float(distance), (int(g1), int(g2))
    if found[0] < 0:
        return best, ("", "")
    a, b = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
            for g in found)
    return best, (a, b)
