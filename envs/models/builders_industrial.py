"""MuJoCo trees of the industrial arms: the OPW family and Universal Robots.

Both are built joint by joint from the kinematics' own parameters, so the site ``ee`` is
``arm.fk`` exactly (the tests check 1e-9 on seeded configurations, turns included):

- **OPW** (``opw``, ``kuka_kr6_r700``, ``abb_irb2400/2600/4600``): the chain
  Rz(θ1)·T(a1, b, c1)·Ry(θ2)·T(0, 0, c2)·Ry(θ3)·T(a2, 0, c3)·Rz(θ4)·Ry(θ5)·Rz(θ6)·T(0, 0, c4)
  with θ = joint·sign − offset: each body is turned by −offset about its joint axis and
  the hinge axis carries the sign, so ``qpos`` holds the controller's joint values and a
  hinge's range is the data sheet's. ``ee`` is the flange (``fk``).
- **UR** (``ur``, ``ur5e``, ``ur10e``): UR's standard DH chain Rz(θi)·Tz(di)·Tx(ai)·Rx(αi):
  body i + 1 sits at (ai, 0, di) in body i, turned Rx(αi), its hinge about its own z.
  ``ee`` is tool0.

Link solids are sized from the lengths (capsules along each link, housings along each
joint axis, radii proportional to the arm's scale), split into visual and collision twins
like every arm here. In the drawn models (``collision_shapes="drawn"``) only a joint's
own two sides are excluded: the OPW roll housing ends 0.85 of the wrist setback behind
the wrist centre, where the flange clears it up to the bend's data-sheet limit, and the
UR wrist keeps its two exclusions, which tests/envs/models/test_builders.py shows never
hide an overlap of the drawn parts. The earlier models excluded the wrist bodies (j4–j6,
and each with the link before the wrist) from each other.
``tool=True`` adds the held tool: a 0.35 m cylinder along the flange normal (body ``tool``).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from typing import TYPE_CHECKING, cast

import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.opw import OpwArm
from ikbranch_gym.envs.kinematics.rotations import axis_quaternion
from ikbranch_gym.envs.kinematics.ur import UrArm

from .builders import (
    DARK,
    ORANGE,
    STEEL,
    TOOL_LENGTH,
    TOOL_RADIUS,
    TOOL_RGBA,
    ArmTree,
    add_part,
    add_static_body,
    exclude,
    register_tree_builder,
)

OPW_ARMS = ("opw", "kuka_kr6_r700", "abb_irb2400", "abb_irb2600", "abb_irb4600")
UR_ARMS = ("ur", "ur5e", "ur10e")

if TYPE_CHECKING:
    import mujoco


def _joint_body(parent: mujoco.MjsBody, arm: Arm, index: int, axis: str, sign: float,
                pos: ArrayLike, quat: ArrayLike) -> mujoco.MjsBody:
    """Body ``link_<joint>`` at ``pos``/``quat`` in ``parent`` with the arm's joint ``index``
    as a hinge about ``sign`` times the local ``axis``, ranged by the arm's limits."""
    import mujoco

    name = arm.joint_names[index]
    body = parent.add_body()
    body.name = f"link_{name}"
    body.pos = np.asarray(pos, dtype=float)
    body.quat = np.asarray(quat, dtype=float)
    joint = body.add_joint()
    joint.name = name
    joint.type = mujoco.mjtJoint.mjJNT_HINGE
    unit = np.zeros(3)
    unit["xyz".index(axis)] = sign
    joint.axis = unit
    joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    joint.range = np.asarray(arm.joint_limits[index], dtype=float)
    # Damping and armature only keep a passive mj_step well behaved; the envs never
    # integrate dynamics.
    joint.damping = np.array([50.0, 0.0, 0.0])
    joint.armature = 1.0
    return body


def _site(body: mujoco.MjsBody, name: str, pos: ArrayLike = (0.0, 0.0, 0.0)) -> None:
    site = body.add_site()
    site.name = name
    site.pos = np.asarray(pos, dtype=float)
    site.size = np.array([0.03, 0.0, 0.0])


def _tool(spec: mujoco.MjSpec, tree: ArmTree, flange: mujoco.MjsBody, start: float) -> None:
    holder = flange.add_body()  # welded: moves with the flange, named for reports
    holder.name = "tool"
    add_part(holder, "tool", "cylinder", [TOOL_RADIUS], TOOL_RGBA,
             fromto=[0, 0, start, 0, 0, start + TOOL_LENGTH])
    tree.tool_body = holder.name


def _excludes(spec: mujoco.MjSpec, pairs: Iterable[tuple[str, str]]) -> None:
    for a, b in pairs:
        exclude(spec, a, b)


def build_opw(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
              collision_shapes: str = "drawn") -> ArmTree:
    """An OPW arm (module docstring): base plinth, turning column with the shoulder
    housing, upper arm (c2), elbow offset and forearm (a2, c3), roll/bend/flange wrist."""
    arm = cast(OpwArm, arm)
    scale = (arm.c2 + arm.c3) / 2
    signs, offsets = arm.sign_corrections, arm.offsets
    tree = ArmTree(collision_shapes=collision_shapes)
    base = add_static_body(spec, "base")
    plinth = max(0.5 * arm.c1, 0.05)
    add_part(base, "plinth", "cylinder", [0.35 * scale], DARK,
             fromto=[0, 0, 0, 0, 0, plinth])
    j1 = _joint_body(base, arm, 0, "z", signs[0], (0, 0, 0), axis_quaternion("z", -offsets[0]))
    add_part(j1, "column", "capsule", [0.25 * scale],
             ORANGE, fromto=[0, 0, plinth + 0.26 * scale, 0, 0, arm.c1])
    add_part(j1, "shoulder", "capsule", [0.2 * scale], DARK,
             fromto=[arm.a1, arm.b - 0.3 * scale, arm.c1, arm.a1, arm.b + 0.3 * scale, arm.c1])
    j2 = _joint_body(j1, arm, 1, "y", signs[1], (arm.a1, arm.b, arm.c1),
                     axis_quaternion("y", -offsets[1]))
    add_part(j2, "upper_arm", "capsule", [0.16 * scale], ORANGE, fromto=[0, 0, 0, 0, 0, arm.c2])
    add_part(j2, "elbow", "capsule", [0.15 * scale], DARK,
             fromto=[0, -0.22 * scale, arm.c2, 0, 0.22 * scale, arm.c2])
    j3 = _joint_body(j2, arm, 2, "y", signs[2], (0, 0, arm.c2), axis_quaternion("y", -offsets[2]))
    setback = 0.3 * scale
    if abs(arm.a2) > 0.15 * scale:
        add_part(j3, "elbow_offset", "capsule", [0.12 * scale], ORANGE,
                 fromto=[0, 0, 0, arm.a2, 0, 0])
    add_part(j3, "forearm", "capsule", [0.12 * scale], ORANGE,
             fromto=[arm.a2, 0, 0, arm.a2, 0, max(arm.c3 - setback, 0.0)])
    j4 = _joint_body(j3, arm, 3, "z", signs[3], (arm.a2, 0, arm.c3),
                     axis_quaternion("z", -offsets[3]))
    drawn = collision_shapes == "drawn"
    add_part(j4, "roll_housing", "capsule", [0.11 * scale], ORANGE,
             fromto=[0, 0, -setback, 0, 0, -(0.85 if drawn else 0.45) * setback])
    j5 = _joint_body(j4, arm, 4, "y", signs[4], (0, 0, 0), axis_quaternion("y", -offsets[4]))
    add_part(j5, "bend_housing", "capsule", [0.09 * scale], DARK,
             fromto=[0, -0.1 * scale, 0, 0, 0.1 * scale, 0])
    j6 = _joint_body(j5, arm, 5, "z", signs[5], (0, 0, 0), axis_quaternion("z", -offsets[5]))
    add_part(j6, "flange", "cylinder", [0.07 * scale], STEEL,
             fromto=[0, 0, 0.35 * arm.c4, 0, 0, arm.c4])
    _site(j6, "ee", (0, 0, arm.c4))
    tree.bodies += ["base", j1.name, j2.name, j3.name, j4.name, j5.name, j6.name]
    tree.ee_body = j6.name
    chain = tree.bodies
    _excludes(spec, itertools.pairwise(chain))
    if not drawn:
        # The earlier models' wrist bodies overlapped near the wrist centre.
        _excludes(spec, [(j3.name, j5.name), (j3.name, j6.name), (j4.name, j6.name)])
    if tool:
        _tool(spec, tree, j6, arm.c4)
        if not drawn:
            _excludes(spec, [(j4.name, "tool"), (j5.name, "tool")])
    return tree


#: UR's DH α per row (π/2, 0, 0, π/2, −π/2, 0).
_UR_ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)


def build_ur(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
             collision_shapes: str = "drawn") -> ArmTree:
    """A UR arm (module docstring): base, shoulder housing, upper arm (a2) offset by d4
    along the shoulder axis, elbow housing, forearm (a3), three wrist housings."""
    arm = cast(UrArm, arm)
    d, a = arm.dh
    scale = (abs(arm.a2) + abs(arm.a3)) / 2
    tree = ArmTree(collision_shapes=collision_shapes)
    base = add_static_body(spec, "base")
    add_part(base, "base_plate", "cylinder", [0.2 * scale], DARK,
             fromto=[0, 0, 0, 0, 0, 0.35 * arm.d1])
    bodies, parent = [], base
    for index in range(6):
        if index == 0:
            pos, quat = (0.0, 0.0, 0.0), np.array([1.0, 0.0, 0.0, 0.0])
        else:
            pos = (a[index - 1], 0.0, d[index - 1])
            quat = axis_quaternion("x", _UR_ALPHA[index - 1])
        parent = _joint_body(parent, arm, index, "z", 1.0, pos, quat)
        bodies.append(parent)
    base_link, shoulder, elbow, wrist1, wrist2, wrist3 = bodies
    radius = 0.16 * scale
    add_part(base_link, "shoulder_column", "capsule", [radius], ORANGE,
             fromto=[0, 0, 0.35 * arm.d1 + radius, 0, 0, arm.d1])
    # The upper arm runs beside the forearm, d4 out along the (parallel) joint 2–4 axes.
    add_part(shoulder, "shoulder_housing", "capsule", [radius], DARK,
             fromto=[0, 0, -0.2 * scale, 0, 0, arm.d4])
    add_part(shoulder, "upper_arm", "capsule", [0.12 * scale], ORANGE,
             fromto=[0, 0, arm.d4, arm.a2, 0, arm.d4])
    add_part(elbow, "elbow_housing", "capsule", [0.13 * scale], DARK,
             fromto=[0, 0, 0, 0, 0, arm.d4])
    add_part(elbow, "forearm", "capsule", [0.1 * scale], ORANGE,
             fromto=[0.25 * scale * np.sign(arm.a3), 0, 0, arm.a3, 0, 0])
    add_part(wrist1, "wrist1_housing", "capsule", [0.09 * scale], DARK,
             fromto=[0, 0, 0, 0, 0, 0.8 * arm.d4])
    add_part(wrist2, "wrist2_housing", "capsule", [0.09 * scale], DARK,
             fromto=[0, 0, -0.1 * scale, 0, 0, 0.8 * arm.d5])
    add_part(wrist3, "flange", "cylinder", [0.08 * scale], STEEL,
             fromto=[0, 0, 0.3 * arm.d6, 0, 0, arm.d6])
    _site(wrist3, "ee", (0, 0, arm.d6))
    tree.bodies += ["base", *(body.name for body in bodies)]
    tree.ee_body = wrist3.name
    chain = tree.bodies
    _excludes(spec, itertools.pairwise(chain))
    _excludes(spec, [(elbow.name, wrist2.name), (wrist1.name, wrist3.name)])
    if tool:
        _tool(spec, tree, wrist3, arm.d6)
        _excludes(spec, [(wrist1.name, "tool"), (wrist2.name, "tool")])
    return tree


for _name in OPW_ARMS:
    register_tree_builder(_name)(build_opw)
for _name in UR_ARMS:
    register_tree_builder(_name)(build_ur)
