"""Tree builder of the rod mechanism (``envs.kinematics.rod``), a bench-top positioner.

The tree is turntable (q3, hinge about −z on the vertical axis) → block (q1, hinge about
+x at O1) → table (q2, hinge about −x at O4); the site ``ee`` sits at the working point P
on the table, oriented as the table's frame, which is the pose ``arm.fk`` reports
(rotation Rz(−q3)·Rx(q1 − q2)). In the turntable's frame the mechanism's plane is y–z,
the paper's r along +y.

The kinematics put the pivot O1 at z = 0, so the turntable is sunk into the floor: its top
face stands 10 mm proud of it, the support pins' axes lie in the floor plane, and its
contact with the floor is excluded like the base's (it turns in its pit). The linear rods
that drive q1 and q2 close kinematic loops a tree cannot hold; they are left out, and the
support at +a/2 marks the lower anchor of the rods. Every size is a multiple of the arm's
own lengths (l'p, b, a).
"""

from __future__ import annotations

from typing import cast

import mujoco
import numpy as np

from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.rod import RodMechanism

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


@register_tree_builder("rod_mechanism")
def build_rod_mechanism(spec: mujoco.MjSpec, arm: Arm, tool: bool = False,
                        collision_shapes: str = "drawn") -> ArmTree:
    """Turntable with two supports a apart, block link O1O4 (b), table link O4P (l'p) and
    the working table at P; ``tool=True`` stands the held tool on the table along its
    normal (+z of the ``ee`` frame)."""
    arm = cast(RodMechanism, arm)
    b, lpp, a = arm.b, arm.lp_prime, arm.a
    scale = 0.5 * (b + lpp)  # the mechanism's size: link radii and plates follow it
    r_link = 0.08 * scale
    r_pin = 0.1 * scale
    pin_half = 0.2 * scale
    depth = 0.25 * scale  # the turntable's thickness below the floor
    tree = ArmTree(collision_shapes=collision_shapes)

    base = add_static_body(spec, "base")
    radius = a / 2 + 0.35 * scale
    add_part(base, "pit_ring", "cylinder", [radius + 0.03, 0.01], DARK, pos=[0, 0, -0.005])

    turntable = add_link(base, arm, 0, (0, 0, -1))
    add_part(turntable, "turntable", "cylinder", [radius, depth / 2], STEEL,
             pos=[0, 0, 0.01 - depth / 2])
    for side, y in (("o1", -a / 2), ("rod", a / 2)):
        add_part(turntable, f"support_{side}", "capsule", [r_pin], DARK,
                 fromto=[-pin_half, y, 0, pin_half, y, 0])

    # The block turns about +x at O1; at q1 = 0 O1O4 rises at γ in the (y, z) plane.
    block = add_link(turntable, arm, 1, (1, 0, 0), (0, -a / 2, 0))
    o4 = b * np.array([0.0, np.cos(arm.gamma), np.sin(arm.gamma)])
    direction = o4 / b
    # Starts clear of the pin, so the block never reaches down to the floor.
    add_part(block, "block", "capsule", [r_link], ORANGE,
             fromto=np.concatenate([(r_pin + 2.5 * r_link) * direction, o4]))
    add_part(block, "block_hub", "capsule", [r_pin], DARK,
             fromto=[-pin_half, o4[1], o4[2], pin_half, o4[1], o4[2]])

    # The table turns about −x at O4; at q2 = 0, O4P makes ψ with O4O1.
    table = add_link(block, arm, 2, (-1, 0, 0), o4)
    angle = np.pi - arm.psi + arm.gamma  # direction of O4P in (y, z) at q = 0
    p = lpp * np.array([0.0, np.cos(angle), np.sin(angle)])
    plate = 0.45 * lpp
    thickness = 0.06 * scale
    add_part(table, "table_link", "capsule", [0.8 * r_link], ORANGE,
             fromto=np.concatenate([np.zeros(3), p - np.array([0, 0, thickness + 0.8 * r_link])]))
    add_part(table, "table", "box", [plate, plate, thickness / 2], STEEL,
             pos=p - np.array([0.0, 0.0, thickness / 2]))
    site = table.add_site()
    site.name = "ee"
    site.pos = p
    site.size = np.array([0.02, 0.0, 0.0])
    if tool:
        holder = table.add_body()
        holder.name = "tool"
        add_part(holder, "tool", "cylinder", [TOOL_RADIUS], TOOL_RGBA,
                 fromto=np.concatenate([p, p + np.array([0.0, 0.0, TOOL_LENGTH])]))
        tree.tool_body = holder.name

    tree.bodies += ["base", turntable.name, block.name, table.name]
    for first, second in [("base", turntable.name), (turntable.name, block.name),
                          (block.name, table.name), ("world", turntable.name)]:
        exclude(spec, first, second)
    tree.ee_body = table.name
    return tree
