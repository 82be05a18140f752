"""Tree builders of the two-arm relative-manipulation systems (``envs.kinematics.dual``).

Both arms go into one model: arm 1's three joints, then arm 2's three, are ``qpos[:6]`` in
kinematics order. Each arm's output link carries a site at the frame of the paper's
equations, ``link3`` (arm 1) and ``link4`` (arm 2), oriented as that frame, so the pose
of ``link4`` expressed in ``link3`` is ``arm.fk(q)``. There is no ``ee`` site: no single
world frame is what ``fk`` reports.

``fk`` is a relative pose, so the common base frame Oxyz may stand anywhere in the cell;
each builder lifts it (``BASE_HEIGHT``) so that both arms clear the floor. Static parts
are two bodies, ``base`` (arm 1's pedestal or frame) and ``base2`` (arm 2's). Only each
arm's own joints are excluded (a joint's two sides); every contact between the two arms
is an arm–arm collision, and each arm's non-adjacent links collide with each other.

``tool=True`` adds the held tool (``TOOL_LENGTH``, body ``tool``) to arm 2's output link,
continuing link 4 outwards along its axis from the ``link4`` frame.
"""

from __future__ import annotations

import itertools
from typing import cast

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.dual import DualPprPrrArm, DualRrpRppArm, DualRrrPppArm

from .builders import (
    DARK,
    ORANGE,
    STEEL,
    TOOL_LENGTH,
    TOOL_RADIUS,
    TOOL_RGBA,
    ArmTree,
    add_link,
    add_part,
    add_static_body,
    exclude,
    register_tree_builder,
)

#: Arm 2's colour, so that the two arms are told apart in pictures.
BLUE = (0.20, 0.42, 0.80, 1.0)
#: Height (m) of the common base frame O above the floor, per system.
BASE_HEIGHT = {"dual_rrp_rpp": 0.8, "dual_rrr_ppp": 0.3, "dual_ppr_prr": 0.5}
#: RRR–PPP: the gantry's tower stands this far (m) beside its ram (+y), which runs past it.
TOWER_OFFSET = 0.2


def add_frame_site(body: mujoco.MjsBody, name: str, pos: ArrayLike = (0.0, 0.0, 0.0)) -> None:
    """A site oriented as ``body``'s frame at ``pos``."""
    site = body.add_site()
    site.name = name
    site.pos = np.asarray(pos, dtype=float)
    site.size = np.array([0.03, 0.0, 0.0])


def add_tool(spec: mujoco.MjSpec, tree: ArmTree, body: mujoco.MjsBody, start: ArrayLike,
             direction: ArrayLike) -> None:
    """The held tool, welded to ``body``, from ``start`` along the unit ``direction``."""
    start, direction = np.asarray(start, dtype=float), np.asarray(direction, dtype=float)
    holder = body.add_body()  # welded: moves with its parent, named for reports
    holder.name = "tool"
    add_part(holder, "tool", "cylinder", [TOOL_RADIUS], TOOL_RGBA,
             fromto=np.concatenate([start, start + TOOL_LENGTH * direction]))
    tree.tool_body = holder.name


def _segmented_box(body: mujoco.MjsBody, name: str, lo: ArrayLike, hi: ArrayLike, axis: int,
                   step: float = 0.5) -> None:
    """The box from corner ``lo`` to ``hi`` as parts ``<name>0``, … at most ``step`` long
    along ``axis``."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    n = int(np.ceil((hi[axis] - lo[axis]) / step))
    cuts = np.linspace(lo[axis], hi[axis], n + 1)
    for k in range(n):
        a, b = lo.copy(), hi.copy()
        a[axis], b[axis] = cuts[k], cuts[k + 1]
        add_part(body, f"{name}{k}", "box", (b - a) / 2, DARK, pos=(a + b) / 2)


def _chains(spec: mujoco.MjSpec, tree: ArmTree, arm1: list[str], arm2: list[str]) -> None:
    """Record both chains (static body first) and exclude each joint's two sides."""
    for chain in (arm1, arm2):
        for a, b in itertools.pairwise(chain):
            exclude(spec, a, b)
    tree.bodies += arm1 + arm2


# ------------------------------------------------------------------------------ RRP–RPP
@register_tree_builder("dual_rrp_rpp")
def build_dual_rrp_rpp(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                       collision_shapes: str = "drawn") -> ArmTree:
    """Arm 1: a pedestal on +x holds the roll axis Ox; the shoulder AB (l1) turns about it
    at A = (a0, 0, 0); at B a turning guide (φ2 about z2) carries the telescope s3 along
    x2, whose tip is C3 (``link3``). Arm 2: a turntable about Oz with its column beside
    the axis; the lift s5 carries the ram s4 along x6 at the lateral offset b0, whose tip
    is C4 (``link4``). O stands 0.8 m above the floor."""
    arm = cast(DualRrpRppArm, arm)
    lim = arm.joint_limits
    height = BASE_HEIGHT[arm.name]
    joint = {name: index for index, name in enumerate(arm.joint_names)}
    tree = ArmTree(collision_shapes=collision_shapes)

    # Arm 1: pedestal beyond A on +x, so the roll axis stays clear of arm 2's column.
    base = add_static_body(spec, "base")
    x0 = arm.a0 + 0.17
    add_part(base, "roll_bearing", "box", [0.12, 0.12, 0.12], DARK,
             pos=[x0 + 0.12, 0, height])
    add_part(base, "pedestal", "box", [0.09, 0.09, (height - 0.12) / 2], DARK,
             pos=[x0 + 0.12, 0, (height - 0.12) / 2])
    add_part(base, "pedestal_foot", "box", [0.16, 0.16, 0.02], DARK, pos=[x0 + 0.12, 0, 0.02])
    shoulder = add_link(base, arm, 0, (1, 0, 0), (arm.a0, 0, height))
    add_part(shoulder, "roll_hub", "capsule", [0.09], ORANGE, fromto=[0.06, 0, 0, 0.17, 0, 0])
    add_part(shoulder, "shoulder", "capsule", [0.06], ORANGE,
             fromto=[0, 0, 0, 0, 0, arm.l1 - 0.15])
    guide = add_link(shoulder, arm, 1, (0, 0, 1), (0, 0, arm.l1))
    add_part(guide, "turn_hub", "capsule", [0.07], DARK, fromto=[0, 0, -0.12, 0, 0, -0.06])
    add_part(guide, "guide", "box", [0.16, 0.07, 0.07], DARK)
    telescope = add_link(guide, arm, 2, (1, 0, 0))
    # The telescope's tail stays in the guide (|x| < 0.16) at full stroke.
    tail = 0.1 - lim[2, 1]
    add_part(telescope, "telescope", "capsule", [0.045], ORANGE, fromto=[tail, 0, 0, -0.05, 0, 0])
    add_part(telescope, "flange3", "cylinder", [0.06], STEEL, fromto=[-0.04, 0, 0, 0, 0, 0])
    add_frame_site(telescope, "link3")

    # Arm 2: turntable on the floor, column at y6 = b0 + 0.16, carriage, ram at y6 = b0.
    base2 = add_static_body(spec, "base2")
    add_part(base2, "plinth", "cylinder", [0.30, 0.025], DARK, pos=[0, 0, 0.025])
    turn = add_link(base2, arm, joint["phi6"], (0, 0, 1), (0, 0, height))
    column_y = arm.b0 + 0.16
    column_top = lim[joint["s5"], 1] + 0.2
    add_part(turn, "turntable", "cylinder", [0.26, 0.03], BLUE, pos=[0, 0, 0.08 - height])
    add_part(turn, "column", "capsule", [0.07], BLUE,
             fromto=[0, column_y, 0.12 - height, 0, column_y, column_top])
    lift = add_link(turn, arm, joint["s5"], (0, 0, 1))
    add_part(lift, "carriage", "box", [0.12, (column_y - arm.b0) / 2 + 0.09, 0.11], DARK,
             pos=[0, (column_y + arm.b0) / 2, 0])
    ram = add_link(lift, arm, joint["s4"], (1, 0, 0), (0, arm.b0, 0))
    tail = 0.1 - lim[joint["s4"], 1]
    add_part(ram, "ram", "capsule", [0.05], BLUE, fromto=[tail, 0, 0, -0.05, 0, 0])
    add_part(ram, "flange4", "cylinder", [0.065], STEEL, fromto=[-0.04, 0, 0, 0, 0, 0])
    add_frame_site(ram, "link4")
    if tool:
        add_tool(spec, tree, ram, (0, 0, 0), (1, 0, 0))

    _chains(spec, tree, ["base", shoulder.name, guide.name, telescope.name],
            ["base2", turn.name, lift.name, ram.name])
    tree.ee_body = ram.name
    return tree


# ------------------------------------------------------------------------------ RRR–PPP
@register_tree_builder("dual_rrr_ppp")
def build_dual_rrr_ppp(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                       collision_shapes: str = "drawn") -> ArmTree:
    """Arm 1: a column rising h above O, turning φ1 about Oz; link AB (l1) along x1, roll
    φ2 about x1 at B, link BC (l2) along z2, turn φ3 about z3 at C, link CC3 (l3) along x3
    to ``link3``. Arm 2: a Cartesian robot beside arm 1 on +x: a tower riding floor rails
    along y (s4), a carriage lifting on it (s5) and a horizontal ram along x (s6) running
    past the tower, its tip pointing −x towards arm 1 at C4 = (s6, b0 + s4, h + s5)
    (``link4``). O stands 0.3 m above the floor, so the ram's lowest stroke (C4 level
    with O) clears the rails."""
    arm = cast(DualRrrPppArm, arm)
    lim = arm.joint_limits
    height = BASE_HEIGHT[arm.name]
    tree = ArmTree(collision_shapes=collision_shapes)

    base = add_static_body(spec, "base")
    add_part(base, "plinth", "cylinder", [0.22, 0.025], DARK, pos=[0, 0, 0.025])
    add_part(base, "column", "capsule", [0.1], DARK,
             fromto=[0, 0, 0, 0, 0, height + arm.h - 0.22])
    turn = add_link(base, arm, 0, (0, 0, 1), (0, 0, height + arm.h))
    add_part(turn, "turret", "capsule", [0.1], ORANGE, fromto=[0, 0, -0.1, 0, 0, 0])
    add_part(turn, "bar1", "capsule", [0.07], ORANGE, fromto=[0, 0, 0, arm.l1 - 0.1, 0, 0])
    roll = add_link(turn, arm, 1, (1, 0, 0), (arm.l1, 0, 0))
    add_part(roll, "roll_hub", "capsule", [0.07], DARK, fromto=[-0.04, 0, 0, 0.04, 0, 0])
    add_part(roll, "bar2", "capsule", [0.06], ORANGE, fromto=[0, 0, 0, 0, 0, arm.l2 - 0.1])
    wrist = add_link(roll, arm, 2, (0, 0, 1), (0, 0, arm.l2))
    add_part(wrist, "turn_hub", "capsule", [0.06], DARK, fromto=[0, 0, -0.04, 0, 0, 0.03])
    add_part(wrist, "bar3", "capsule", [0.05], ORANGE, fromto=[0, 0, 0, arm.l3 - 0.05, 0, 0])
    add_part(wrist, "flange3", "cylinder", [0.06], STEEL,
             fromto=[arm.l3 - 0.04, 0, 0, arm.l3, 0, 0])
    add_frame_site(wrist, "link3", (arm.l3, 0, 0))

    # Arm 2. The tower stands TOWER_OFFSET beside the ram, 0.6 m beyond the ram tip's +x
    # end; the ram's tail stays in the carriage at the −x end of s6.
    tower_x = lim[5, 1] + 0.6
    y_lo, y_hi = arm.b0 + lim[3, 0], arm.b0 + lim[3, 1]
    z0 = height + arm.h  # C4's height at s5 = 0
    base2 = add_static_body(spec, "base2")
    for side, dx in (("l", -0.18), ("r", 0.18)):
        add_part(base2, f"rail_{side}", "box", [0.04, (y_hi - y_lo) / 2 + 0.3, 0.03], DARK,
                 pos=[tower_x + dx, (y_lo + y_hi) / 2 + TOWER_OFFSET, 0.03])
    tower = add_link(base2, arm, 3, (0, 1, 0), (0, arm.b0, z0))
    top = lim[4, 1] + 0.25
    add_part(tower, "tower_foot", "box", [0.25, 0.2, 0.04], BLUE,
             pos=[tower_x, TOWER_OFFSET, 0.10 - z0])
    add_part(tower, "tower", "box", [0.08, 0.08, (top + z0 - 0.14) / 2], BLUE,
             pos=[tower_x, TOWER_OFFSET, (top - z0 + 0.14) / 2])
    lift = add_link(tower, arm, 4, (0, 0, 1))
    add_part(lift, "carriage", "box", [0.14, TOWER_OFFSET / 2 + 0.1, 0.1], DARK,
             pos=[tower_x, TOWER_OFFSET / 2, 0])
    ram = add_link(lift, arm, 5, (1, 0, 0))
    tail = tower_x + 0.1 - lim[5, 0]
    add_part(ram, "ram", "capsule", [0.05], BLUE, fromto=[0.05, 0, 0, tail, 0, 0])
    add_part(ram, "flange4", "cylinder", [0.065], STEEL, fromto=[0, 0, 0, 0.04, 0, 0])
    add_frame_site(ram, "link4")
    if tool:
        add_tool(spec, tree, ram, (0, 0, 0), (-1, 0, 0))

    _chains(spec, tree, ["base", turn.name, roll.name, wrist.name],
            ["base2", tower.name, lift.name, ram.name])
    tree.ee_body = ram.name
    return tree


# ------------------------------------------------------------------------------ PPR–PRR
@register_tree_builder("dual_ppr_prr")
def build_dual_ppr_prr(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                       collision_shapes: str = "drawn") -> ArmTree:
    """Arm 1: an overhead XY frame, bridge s1 along Ox, carriage s2 along Oy, a quill down
    to the turn φ3 about the vertical at height l1 above O; link 3 (l3) along x3 to C3
    (``link3``). Arm 2: a fixed column behind the tilt axis (−x), a carriage lifting s4
    carrying E = (0, 0, s4); the tilt φ5 about x at E, link ED (l5) along z5, the turn φ6
    about z5 at D and link 4 (l4) along x4 to C4 (``link4``). O stands 0.5 m above the
    floor, so the lift's lowest E clears it."""
    arm = cast(DualPprPrrArm, arm)
    lim = arm.joint_limits
    height = BASE_HEIGHT[arm.name]
    tree = ArmTree(collision_shapes=collision_shapes)

    # Arm 1: the frame's rails run along x, above the turn by 0.5 m.
    pivot_z = height + arm.l1
    rail_z = pivot_z + 0.5
    reach = arm.l3 + 0.15
    x_half = max(abs(lim[0, 0]), abs(lim[0, 1])) + reach
    y_half = max(abs(lim[1, 0]), abs(lim[1, 1])) + reach
    # Legs and rails in short segments: scenes test footprints with bounding spheres, and
    # one long part's sphere would fence off the whole cell (random_clutter).
    base = add_static_body(spec, "base")
    for sx in (-1, 1):
        for sy in (-1, 1):
            x, y = sx * x_half, sy * y_half
            _segmented_box(base, f"leg_{'mp'[sx > 0]}{'mp'[sy > 0]}", (x - 0.07, y - 0.07, 0),
                           (x + 0.07, y + 0.07, rail_z), axis=2)
    for sy in (-1, 1):
        _segmented_box(base, f"rail_{'mp'[sy > 0]}", (-x_half - 0.07, sy * y_half - 0.07,
                       rail_z - 0.07), (x_half + 0.07, sy * y_half + 0.07, rail_z + 0.07), axis=0)
    bridge = add_link(base, arm, 0, (1, 0, 0), (0, 0, height))
    add_part(bridge, "bridge", "box", [0.08, y_half, 0.08], ORANGE,
             pos=[0, 0, rail_z + 0.15 - height])
    carriage = add_link(bridge, arm, 1, (0, 1, 0))
    add_part(carriage, "carriage", "box", [0.16, 0.14, 0.1], ORANGE,
             pos=[0, 0, rail_z + 0.02 - height])
    add_part(carriage, "quill", "capsule", [0.07], STEEL,
             fromto=[0, 0, arm.l1 + 0.12, 0, 0, rail_z - 0.08 - height])
    turn = add_link(carriage, arm, 2, (0, 0, 1), (0, 0, arm.l1))
    add_part(turn, "turn_hub", "capsule", [0.08], DARK, fromto=[0, 0, -0.02, 0, 0, 0.04])
    add_part(turn, "bar3", "capsule", [0.05], ORANGE, fromto=[0, 0, 0, arm.l3 - 0.05, 0, 0])
    add_part(turn, "flange3", "cylinder", [0.06], STEEL,
             fromto=[arm.l3 - 0.04, 0, 0, arm.l3, 0, 0])
    add_frame_site(turn, "link3", (arm.l3, 0, 0))

    # Arm 2: the column stands behind E on the tilt axis (−x), clear of link 5's swing.
    column_x = -0.3
    base2 = add_static_body(spec, "base2")
    add_part(base2, "plinth", "box", [0.2, 0.2, 0.025], DARK, pos=[column_x, 0, 0.025])
    add_part(base2, "column", "capsule", [0.09], DARK,
             fromto=[column_x, 0, 0, column_x, 0, height + lim[3, 1] + 0.05])
    lift = add_link(base2, arm, 3, (0, 0, 1), (0, 0, height))
    add_part(lift, "lift_carriage", "box", [0.13, 0.13, 0.12], BLUE, pos=[column_x, 0, 0])
    add_part(lift, "shaft", "capsule", [0.06], STEEL, fromto=[column_x + 0.12, 0, 0, -0.1, 0, 0])
    tilt = add_link(lift, arm, 4, (1, 0, 0))
    add_part(tilt, "tilt_hub", "capsule", [0.08], DARK, fromto=[-0.06, 0, 0, 0.06, 0, 0])
    add_part(tilt, "bar5", "capsule", [0.06], BLUE, fromto=[0, 0, 0, 0, 0, arm.l5 - 0.1])
    head = add_link(tilt, arm, 5, (0, 0, 1), (0, 0, arm.l5))
    add_part(head, "head_hub", "capsule", [0.06], DARK, fromto=[0, 0, -0.05, 0, 0, 0.03])
    add_part(head, "bar4", "capsule", [0.05], BLUE, fromto=[0, 0, 0, arm.l4 - 0.05, 0, 0])
    add_part(head, "flange4", "cylinder", [0.06], STEEL,
             fromto=[arm.l4 - 0.04, 0, 0, arm.l4, 0, 0])
    add_frame_site(head, "link4", (arm.l4, 0, 0))
    if tool:
        add_tool(spec, tree, head, (arm.l4, 0, 0), (1, 0, 0))

    _chains(spec, tree, ["base", bridge.name, carriage.name, turn.name],
            ["base2", lift.name, tilt.name, head.name])
    tree.ee_body = head.name
    return tree
