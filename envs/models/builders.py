"""Per-arm kinematic trees built with ``mujoco.MjSpec`` from the kinematics' own parameters.

Every builder reads the arm's dimensions, joint limits and joint order from the ``Arm``
instance, so the MuJoCo model and ``arm.fk`` cannot drift apart: the first ``arm.dof``
entries of ``qpos`` are the arm's joints in kinematics order, each hinge/slide axis passes
through its body's origin, and slides sit at zero offset along their axis so that
``qpos = s`` means a displacement of exactly ``s`` metres. The site ``ee`` is the frame
``arm.fk`` reports (position and orientation).

Geometry follows the usual MuJoCo split: every link part is added twice, as a visual geom
(group 2, no contacts, massless) and as a collision geom (group 3, ``contype = conaffinity =
1``, carries the mass). With ``collision_shapes="drawn"`` (the current models) the
collision geom is the drawn shape itself, cylinders included, and the only contacts
excluded are a joint's own: a body and its parent (MuJoCo's rule; written out where the
parent is welded to the world). Every other pair of arm bodies is a real self-collision,
so the parts are shaped to clear each other within the joint limits (a wrist's housings
are set back from its centre; a slide's guide surrounds only its own beam).
``collision_shapes="inscribed"`` builds the earlier models the first registered ids keep:
a cylinder collided as the capsule inside it (a disc as the box around it), the wrist's
and the guides' overlapping parts excluded from each other (docs/models.md measures what
that leaves out).

A new arm type registers a tree builder with :func:`register_tree_builder`; two-arm systems
are expected to add the sites ``link3`` and ``link4`` (their relative-pose frames) and need
nothing else here, because contacts between any two collision geoms are counted.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import cast

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.anthropomorphic import AnthropomorphicArm
from ikbranch_gym.envs.kinematics.spherical import SphericalArm

#: Geom groups: MuJoCo's renderer shows groups 0–2 by default, so collision geoms (3) stay
#: hidden unless asked for.
VISUAL_GROUP, COLLISION_GROUP = 2, 3
#: Contact bit shared by every collision geom (arm links, obstacles, floor).
COLLISION_BIT = 1

#: The positioning part of every six-DOF arm ends this far (m) behind the wrist centre along
#: the wrist's roll axis; the roll housing fills the gap, so wrist parts never overlap the
#: link in front of them.
WRIST_SETBACK = 0.25
#: Length (m) of the held tool along y3 (the worked example's b = 350 mm) and its radius.
TOOL_LENGTH, TOOL_RADIUS = 0.35, 0.025

ORANGE = (0.93, 0.45, 0.10, 1.0)
DARK = (0.22, 0.22, 0.25, 1.0)
STEEL = (0.62, 0.64, 0.68, 1.0)
TOOL_RGBA = (0.85, 0.80, 0.20, 1.0)
COLLISION_RGBA = (0.2, 0.6, 0.9, 0.35)


#: The two generations of collision shapes (module docstring): the drawn shapes, or the
#: earlier inscribed ones.
COLLISION_SHAPES = ("drawn", "inscribed")


def check_collision_shapes(collision_shapes: str) -> str:
    if collision_shapes not in COLLISION_SHAPES:
        raise ValueError(f"collision_shapes must be one of {', '.join(COLLISION_SHAPES)}, "
                         f"not {collision_shapes!r}")
    return collision_shapes


@dataclass
class ArmTree:
    """What a tree builder reports: bodies in chain order, the wrist/tool body names, and
    the generation of collision shapes the model is built with."""

    bodies: list[str] = field(default_factory=list)
    ee_body: str = ""
    tool_body: str | None = None
    collision_shapes: str = "drawn"


#: ``builder(spec, arm, tool, collision_shapes) -> ArmTree``.
TreeBuilder = Callable[[mujoco.MjSpec, Arm, bool, str], ArmTree]
TREE_BUILDERS: dict[str, TreeBuilder] = {}


def register_tree_builder(name: str) -> Callable[[TreeBuilder], TreeBuilder]:
    """Decorator: register ``builder(spec, arm, tool, collision_shapes) -> ArmTree`` for the
    arm ``name``."""

    def decorate(builder: TreeBuilder) -> TreeBuilder:
        if name in TREE_BUILDERS:
            raise ValueError(f"a tree builder for arm {name!r} is already registered")
        TREE_BUILDERS[name] = builder
        return builder

    return decorate


# --------------------------------------------------------------------------------- helpers
_GEOM_TYPES = {
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
}


def add_part(
    body: mujoco.MjsBody,
    name: str,
    kind: str,
    size: ArrayLike,
    rgba: Sequence[float],
    *,
    fromto: ArrayLike | None = None,
    pos: ArrayLike | None = None,
    quat: ArrayLike | None = None,
) -> None:
    """Add one link part as a visual geom ``<name>_vis`` and a collision geom ``<name>`` of
    the same shape (:func:`compile_spec` inscribes the cylinders of the earlier models)."""
    size = np.asarray(size, dtype=float)
    for visual in (True, False):
        geom = body.add_geom()
        geom.name = f"{name}_vis" if visual else name
        geom.type = _GEOM_TYPES[kind]
        geom.size = np.resize(size, 3)
        if fromto is not None:
            geom.fromto = np.asarray(fromto, dtype=float)
        if pos is not None:
            geom.pos = np.asarray(pos, dtype=float)
        if quat is not None:
            geom.quat = np.asarray(quat, dtype=float)
        if visual:
            geom.contype = geom.conaffinity = 0
            geom.group = VISUAL_GROUP
            geom.density = 0.0  # the collision twin carries the mass
            geom.rgba = rgba
        else:
            geom.contype = geom.conaffinity = COLLISION_BIT
            geom.group = COLLISION_GROUP
            geom.rgba = COLLISION_RGBA
            geom.density = 500.0  # hollow steel links, roughly


def inscribe_cylinders(spec: mujoco.MjSpec) -> None:
    """The earlier models' collision cylinders: each turned into the capsule inside it (a
    disc, lower than it is wide, into the box around it), which MuJoCo collided with its
    fast primitive colliders."""
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_CYLINDER and geom.contype:
            fromto = None if np.isnan(geom.fromto[0]) else np.array(geom.fromto)
            _cylinder_to_primitive(geom, np.array(geom.size), fromto)


def _cylinder_to_primitive(geom: mujoco.MjsGeom, size: np.ndarray,
                           fromto: np.ndarray | None) -> None:
    radius = size[0]
    if fromto is not None:
        ends = fromto.reshape(2, 3)
        length = np.linalg.norm(ends[1] - ends[0])
        half = length / 2
        centre, axis = ends.mean(axis=0), (ends[1] - ends[0]) / max(length, 1e-12)
    else:
        half, centre, axis = size[1], None, None
    if half >= radius:
        geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
        if fromto is not None:
            inner = half - radius
            geom.fromto = np.concatenate([centre - inner * axis, centre + inner * axis])
        else:
            geom.size = np.array([radius, half - radius, 0.0])
    else:  # a disc: the box around it (fromto keeps the axis; size gives the x/y halves)
        geom.type = mujoco.mjtGeom.mjGEOM_BOX
        geom.size = np.array([radius, radius, half])


def compile_spec(spec: mujoco.MjSpec,
                 primitive_boxes: Callable[[str], bool] | None = None, *,
                 collision_shapes: str = "drawn") -> mujoco.MjModel:
    """Compile ``spec`` with every collision box turned into an 8-vertex convex mesh (and,
    for ``collision_shapes="inscribed"``, every collision cylinder inscribed first:
    :func:`inscribe_cylinders`).

    ``primitive_boxes(name)`` True keeps that box a box: a mesh cannot be resized at run
    time, and the per-episode clutter's obstacle slots must be. Those boxes only ever meet
    capsules and meshes (every arm box is a mesh), never the box–box collider below.

    MuJoCo's box–box collider misses pairs inside their contact margin in some
    orientations (google-deepmind/mujoco#2471): in an Anthropomorphic-v0 path, the
    gripper box came within 8.8 mm of an obstacle box (``mj_geomDistance``) while
    ``mj_collision`` reported nothing even with a 0.2 m margin. The same boxes as meshes go
    through the general convex solver, whose distances match ``mj_geomDistance`` (see
    tests/envs/models/test_collision.py). Visual geoms stay boxes. A box's frame (possibly
    set by ``fromto``) is taken from a first compile, so the mesh lands exactly on it.
    """
    if check_collision_shapes(collision_shapes) == "inscribed":
        inscribe_cylinders(spec)
    first = spec.compile()
    boxes = [
        g for g in range(first.ngeom)
        if first.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX and first.geom_contype[g]
        and not (primitive_boxes and primitive_boxes(first.geom(g).name))
    ]
    if not boxes:
        return first
    corners = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    for g in boxes:
        name = first.geom(g).name
        mesh = spec.add_mesh()
        mesh.name = f"{name}_hull"
        mesh.uservert = (corners * first.geom_size[g]).ravel()
        geom = spec.geom(name)
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = mesh.name
        geom.fromto = np.full(6, np.nan)
        geom.pos = first.geom_pos[g].copy()
        geom.quat = first.geom_quat[g].copy()
    return spec.compile()


def add_static_body(spec: mujoco.MjSpec, name: str,
                    parent: mujoco.MjsBody | None = None) -> mujoco.MjsBody:
    """A body without joints under ``parent`` (default the world): fixed in the world."""
    body = (spec.worldbody if parent is None else parent).add_body()
    body.name = name
    return body


def add_link(
    parent: mujoco.MjsBody, arm: Arm, index: int, axis: ArrayLike,
    pos: ArrayLike = (0.0, 0.0, 0.0),
) -> mujoco.MjsBody:
    """Child body ``link_<joint>`` at ``pos`` carrying the arm's joint ``index``.

    The joint sits at the body origin (so the axis passes through it); its range is the
    arm's limit, in radians for hinges (the spec compiles in radians).
    """
    name = arm.joint_names[index]
    body = parent.add_body()
    body.name = f"link_{name}"
    body.pos = np.asarray(pos, dtype=float)
    joint = body.add_joint()
    joint.name = name
    joint.type = (
        mujoco.mjtJoint.mjJNT_HINGE
        if arm.joint_types[index] == "revolute"
        else mujoco.mjtJoint.mjJNT_SLIDE
    )
    joint.axis = np.asarray(axis, dtype=float)
    joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    joint.range = np.asarray(arm.joint_limits[index], dtype=float)
    # Damping and armature only keep a passive mj_step well behaved; the envs never
    # integrate dynamics.
    joint.damping = np.array([50.0, 0.0, 0.0])  # polynomial coefficients, linear first
    joint.armature = 1.0
    return body


def exclude(spec: mujoco.MjSpec, first: str, second: str) -> None:
    pair = spec.add_exclude()
    pair.bodyname1, pair.bodyname2 = first, second


def add_spherical_wrist(
    spec: mujoco.MjSpec,
    tree: ArmTree,
    parent: mujoco.MjsBody,
    arm: Arm,
    first: int,
    tool: bool,
    pos: ArrayLike = (0.0, 0.0, 0.0),
) -> None:
    """The papers' Y–X–Y wrist (joints ``first``..``first+2``), ``ee`` at the wrist centre.

    The roll housing reaches back along −y to the positioning link; the bend housing lies
    along x; the flange and gripper point along +y (the tool axis y3). In the drawn models
    the roll housing ends 0.18 m behind the centre, so the flange clears it by δ up to the
    bend's ±135° limit and no wrist pair is excluded beyond a joint's own two sides.
    """
    drawn = tree.collision_shapes == "drawn"
    roll = add_link(parent, arm, first, (0, 1, 0), pos)
    add_part(roll, "roll_housing", "capsule", [0.07], ORANGE,
             fromto=[0, -WRIST_SETBACK, 0, 0, -0.18 if drawn else -0.12, 0])
    bend = add_link(roll, arm, first + 1, (1, 0, 0))
    add_part(bend, "bend_housing", "capsule", [0.065], DARK, fromto=[-0.07, 0, 0, 0.07, 0, 0])
    flange = add_link(bend, arm, first + 2, (0, 1, 0))
    add_part(flange, "flange", "cylinder", [0.05], STEEL, fromto=[0, 0.02, 0, 0, 0.10, 0])
    add_part(flange, "gripper", "box", [0.06, 0.03, 0.02], DARK, pos=[0, 0.13, 0])
    site = flange.add_site()
    site.name = "ee"
    site.size = np.array([0.03, 0.0, 0.0])
    tree.bodies += [roll.name, bend.name, flange.name]
    tree.ee_body = flange.name
    if tool:
        holder = flange.add_body()  # welded: moves with the flange, named for reports
        holder.name = "tool"
        add_part(holder, "tool", "cylinder", [TOOL_RADIUS], TOOL_RGBA,
                 fromto=[0, 0, 0, 0, TOOL_LENGTH, 0])
        tree.tool_body = holder.name
    for a, b in [(parent.name, roll.name), (roll.name, bend.name), (bend.name, flange.name)]:
        exclude(spec, a, b)
    if not drawn:
        # The earlier models' wrist bodies overlapped near the wrist centre: excluded.
        exclude(spec, roll.name, flange.name)
        if tool:
            exclude(spec, roll.name, "tool")
            exclude(spec, bend.name, "tool")


def _chain_excludes(spec: mujoco.MjSpec, names: list[str]) -> None:
    for a, b in itertools.pairwise(names):
        exclude(spec, a, b)


# ------------------------------------------------------------------------------ the arms
@register_tree_builder("cartesian")
def build_cartesian(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                    collision_shapes: str = "drawn") -> ArmTree:
    """Gantry: s1 along X0 (bridge), s2 along Y0 (carriage), s3 along Z0 (ram), then the
    Y–X–Y wrist at the ram's foot, O = (s1, s2, s3). The ram is 0.3 m behind the wrist
    centre (−y) so that the wrist's roll axis is horizontal like the other arms'."""
    lim = arm.joint_limits
    x_half = max(abs(lim[0, 0]), abs(lim[0, 1])) + 0.6
    y_half = max(abs(lim[1, 0]), abs(lim[1, 1])) + 0.5
    height = lim[2, 1] + 0.6  # rails above the highest wrist position
    ram_offset = 0.3
    tree = ArmTree(collision_shapes=collision_shapes)
    base = add_static_body(spec, "base")
    for sx in (-1, 1):
        for sy in (-1, 1):
            add_part(base, f"leg_{'mp'[sx > 0]}{'mp'[sy > 0]}", "box", [0.08, 0.08, height / 2],
                     DARK, pos=[sx * x_half, sy * y_half, height / 2])
    for sy in (-1, 1):
        add_part(base, f"rail_{'mp'[sy > 0]}", "box", [x_half + 0.08, 0.08, 0.08], DARK,
                 pos=[0, sy * y_half, height])
    bridge = add_link(base, arm, 0, (1, 0, 0))
    # Behind the ram (−x) so that the ram, which sits at x = s1 exactly, clears the beam.
    add_part(bridge, "bridge", "box", [0.1, y_half, 0.1], ORANGE,
             pos=[-0.3, 0, height + 0.18])
    carriage = add_link(bridge, arm, 1, (0, 1, 0))
    add_part(carriage, "carriage", "box", [0.22, 0.15, 0.15], ORANGE,
             pos=[-0.12, -ram_offset, height + 0.12])
    ram = add_link(carriage, arm, 2, (0, 0, 1))
    ram_top = height + 0.35 - lim[2, 0]  # still above the carriage at the lowest stroke
    add_part(ram, "ram", "capsule", [0.08], STEEL,
             fromto=[0, -ram_offset, 0.0, 0, -ram_offset, ram_top])
    add_part(ram, "ram_foot", "capsule", [0.08], STEEL,
             fromto=[0, -ram_offset, 0, 0, -WRIST_SETBACK, 0])
    tree.bodies += ["base", bridge.name, carriage.name, ram.name]
    _chain_excludes(spec, tree.bodies)
    add_spherical_wrist(spec, tree, ram, arm, 3, tool)
    return tree


def _column_lift_turn_radial(spec: mujoco.MjSpec, arm: Arm, tree: ArmTree,
                             radius: float) -> mujoco.MjsBody:
    """The positioning part shared by the cylindrical arms: s1 up the fixed column, φ1
    about Z0, s2 radially along the arm's +y; returns the radial slide's body.

    In the drawn models the radial slide is a fork: two rails beside the column, joined
    by a crosshead in front of it, running in two guides on the turning carriage, so no
    part passes through the column (the earlier models ran one beam through it).
    """
    if tree.collision_shapes == "drawn":
        return _column_lift_turn_fork(spec, arm, tree, radius)
    lim = arm.joint_limits
    base = add_static_body(spec, "base")
    add_part(base, "plate", "cylinder", [0.35, 0.03], DARK, pos=[0, 0, 0.03])
    add_part(base, "column", "cylinder", [0.10], DARK, fromto=[0, 0, 0, 0, 0, lim[0, 1] + 0.25])
    lift = add_link(base, arm, 0, (0, 0, 1))
    add_part(lift, "sleeve", "cylinder", [0.16], ORANGE, fromto=[0, 0, -0.15, 0, 0, 0.15])
    turn = add_link(lift, arm, 1, (0, 0, 1))
    add_part(turn, "guide", "box", [0.14, 0.24, 0.12], ORANGE, pos=[0, 0, 0])
    radial = add_link(turn, arm, 2, (0, 1, 0))
    # Long enough to stay in the guide (|y| < 0.24) at full stroke.
    tail = -lim[2, 1] - 0.2
    add_part(radial, "beam", "capsule", [radius], STEEL,
             fromto=[0, tail, 0, 0, -WRIST_SETBACK, 0])
    tree.bodies += ["base", lift.name, turn.name, radial.name]
    _chain_excludes(spec, tree.bodies)
    # The turn head surrounds the column and the beam runs through the head over the
    # column's axis: built to overlap.
    for a, b in [("base", turn.name), ("base", radial.name), (lift.name, radial.name)]:
        exclude(spec, a, b)
    return radial


#: The drawn cylindrical arms' fork: rails this far either side of the arm axis (m).
FORK_HALF_WIDTH = 0.30


def _column_lift_turn_fork(spec: mujoco.MjSpec, arm: Arm, tree: ArmTree,
                           radius: float) -> mujoco.MjsBody:
    """The drawn positioning part of the cylindrical arms (see the caller): the column
    (r 0.10), the lift's sleeve on it (r 0.13), the carriage's guides and the rails
    (``radius / 2``) at x = ±0.20, the crosshead joining the rails 0.25 m behind the wrist
    centre. The crosshead clears the sleeve once s2 > 0.43 m, where the wrist itself
    clears the column."""
    lim = arm.joint_limits
    rail = radius / 2
    base = add_static_body(spec, "base")
    add_part(base, "plate", "cylinder", [0.35, 0.03], DARK, pos=[0, 0, 0.03])
    add_part(base, "column", "cylinder", [0.10], DARK, fromto=[0, 0, 0, 0, 0, lim[0, 1] + 0.25])
    lift = add_link(base, arm, 0, (0, 0, 1))
    add_part(lift, "sleeve", "cylinder", [0.13], ORANGE, fromto=[0, 0, -0.15, 0, 0, 0.15])
    turn = add_link(lift, arm, 1, (0, 0, 1))
    for side, x in (("m", -FORK_HALF_WIDTH), ("p", FORK_HALF_WIDTH)):
        add_part(turn, f"guide_{side}", "box", [rail + 0.03, 0.24, rail + 0.03], ORANGE,
                 pos=[x, 0, 0])
    radial = add_link(turn, arm, 2, (0, 1, 0))
    # Long enough to stay in the guides (|y| < 0.24) at full stroke.
    tail, front = -lim[2, 1] - 0.2, -WRIST_SETBACK
    for side, x in (("m", -FORK_HALF_WIDTH), ("p", FORK_HALF_WIDTH)):
        add_part(radial, f"rail_{side}", "capsule", [rail], STEEL,
                 fromto=[x, tail, 0, x, front, 0])
    add_part(radial, "crosshead", "capsule", [rail], STEEL,
             fromto=[-FORK_HALF_WIDTH, front, 0, FORK_HALF_WIDTH, front, 0])
    tree.bodies += ["base", lift.name, turn.name, radial.name]
    _chain_excludes(spec, tree.bodies)
    return radial


@register_tree_builder("cylindrical")
def build_cylindrical(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                      collision_shapes: str = "drawn") -> ArmTree:
    """s1 along Z0, φ1 about Z0, s2 radial along the arm's y, then the Y–X–Y wrist:
    O = (−s2 sin φ1, s2 cos φ1, s1)."""
    tree = ArmTree(collision_shapes=collision_shapes)
    radial = _column_lift_turn_radial(spec, arm, tree, 0.07)
    add_spherical_wrist(spec, tree, radial, arm, 3, tool)
    return tree


@register_tree_builder("cylindrical4")
def build_cylindrical4(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                       collision_shapes: str = "drawn") -> ArmTree:
    """The cylindrical arm's positioning part and one gripper rotation φ2 about the arm
    axis y: R = Rz(φ1)·Ry(φ2)."""
    tree = ArmTree(collision_shapes=collision_shapes)
    radial = _column_lift_turn_radial(spec, arm, tree, 0.06)
    grip = add_link(radial, arm, 3, (0, 1, 0))
    add_part(grip, "rotary", "cylinder", [0.06], DARK,
             fromto=[0, -WRIST_SETBACK + 0.02, 0, 0, 0.02, 0])
    # Wide along x so that the φ2 rotation is visible.
    add_part(grip, "gripper", "box", [0.09, 0.04, 0.025], ORANGE, pos=[0, 0.07, 0])
    site = grip.add_site()
    site.name = "ee"
    site.size = np.array([0.03, 0.0, 0.0])
    tree.bodies.append(grip.name)
    tree.ee_body = grip.name
    exclude(spec, radial.name, grip.name)
    if tool:
        holder = grip.add_body()
        holder.name = "tool"
        add_part(holder, "tool", "cylinder", [TOOL_RADIUS], TOOL_RGBA,
                 fromto=[0, 0, 0, 0, TOOL_LENGTH, 0])
        tree.tool_body = holder.name
        exclude(spec, radial.name, "tool")
    return tree


@register_tree_builder("spherical")
def build_spherical(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                    collision_shapes: str = "drawn") -> ArmTree:
    """φ1 about Z0, shoulder at (0, 0, l1), elevation φ2 about x, radial slide s1 along the
    boom's y, then the Y–X–Y wrist: O = (0, 0, l1) + Rz(φ1)·Rx(φ2)·(0, s1, 0)."""
    arm = cast(SphericalArm, arm)
    lim = arm.joint_limits
    tree = ArmTree(collision_shapes=collision_shapes)
    base = add_static_body(spec, "base")
    add_part(base, "pedestal", "cylinder", [0.18], DARK, fromto=[0, 0, 0, 0, 0, arm.l1 - 0.45])
    add_part(base, "plate", "cylinder", [0.35, 0.03], DARK, pos=[0, 0, 0.03])
    turret = add_link(base, arm, 0, (0, 0, 1))
    drawn = collision_shapes == "drawn"
    if drawn:
        # A turntable and two cheeks rising either side of the boom: the ram's tail swings
        # between them, down to the turntable.
        add_part(turret, "turret", "cylinder", [0.22], ORANGE,
                 fromto=[0, 0, arm.l1 - 0.45, 0, 0, arm.l1 - 0.40])
        cheek = (0.45 + 0.14) / 2
        for side, x in (("m", -0.2), ("p", 0.2)):
            add_part(turret, f"yoke_{side}", "box", [0.06, 0.08, cheek], ORANGE,
                     pos=[x, 0, arm.l1 + 0.14 - cheek])
    else:
        add_part(turret, "turret", "cylinder", [0.22], ORANGE,
                 fromto=[0, 0, arm.l1 - 0.45, 0, 0, arm.l1 - 0.12])
        add_part(turret, "yoke", "box", [0.26, 0.08, 0.14], ORANGE, pos=[0, 0, arm.l1])
    boom = add_link(turret, arm, 1, (1, 0, 0), (0, 0, arm.l1))
    add_part(boom, "trunnion", "capsule", [0.1], DARK, fromto=[-0.2, 0, 0, 0.2, 0, 0])
    add_part(boom, "boom", "capsule", [0.12], ORANGE, fromto=[0, -0.25, 0, 0, 0.25, 0])
    ram = add_link(boom, arm, 2, (0, 1, 0))
    # The ram's tail stays inside the boom (front end +0.25) at full stroke.
    add_part(ram, "ram", "capsule", [0.07], STEEL,
             fromto=[0, 0.25 - lim[2, 1], 0, 0, -WRIST_SETBACK, 0])
    tree.bodies += ["base", turret.name, boom.name, ram.name]
    _chain_excludes(spec, tree.bodies)
    if not drawn:
        exclude(spec, turret.name, ram.name)  # the ram slid through the yoke
    add_spherical_wrist(spec, tree, ram, arm, 3, tool)
    return tree


@register_tree_builder("anthropomorphic")
def build_anthropomorphic(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                          collision_shapes: str = "drawn") -> ArmTree:
    """φ1 about Z0 (column), shoulder at (0, 0, l1), φ2 and φ3 about local x, upper arm
    (l2) and forearm (l3) along local y, then the Y–X–Y wrist at the forearm's end."""
    arm = cast(AnthropomorphicArm, arm)
    tree = ArmTree(collision_shapes=collision_shapes)
    base = add_static_body(spec, "base")
    add_part(base, "plinth", "cylinder", [0.3], DARK, fromto=[0, 0, 0, 0, 0, 0.3])
    column = add_link(base, arm, 0, (0, 0, 1))
    add_part(column, "column", "capsule", [0.12], ORANGE, fromto=[0, 0, 0.3, 0, 0, arm.l1])
    add_part(column, "shoulder", "capsule", [0.13], DARK,
             fromto=[-0.18, 0, arm.l1, 0.18, 0, arm.l1])
    upper = add_link(column, arm, 1, (1, 0, 0), (0, 0, arm.l1))
    add_part(upper, "upper_arm", "capsule", [0.10], ORANGE, fromto=[0, 0, 0, 0, arm.l2, 0])
    add_part(upper, "elbow", "capsule", [0.10], DARK,
             fromto=[-0.12, arm.l2, 0, 0.12, arm.l2, 0])
    fore = add_link(upper, arm, 2, (1, 0, 0), (0, arm.l2, 0))
    add_part(fore, "forearm", "capsule", [0.08], ORANGE,
             fromto=[0, 0, 0, 0, max(arm.l3 - WRIST_SETBACK, 0.0), 0])
    tree.bodies += ["base", column.name, upper.name, fore.name]
    _chain_excludes(spec, tree.bodies)
    add_spherical_wrist(spec, tree, fore, arm, 3, tool, pos=(0, arm.l3, 0))
    return tree
