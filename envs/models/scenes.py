"""Scenes: obstacles added to an arm's spec, then compiled.

``empty``
    The floor only (every arm).
``milling_cell``
    Klyuiko's (1986) worked example for the anthropomorphic arm: a tool is taken from a
    horizontal rack (position 1) into the spindle of a vertical milling machine
    (position 2). The cell is laid out around the paper's two poses (see
    :func:`milling_cell_poses`) so that the recommended transfer 1.1 → 2.1 is collision-free
    along its linear joint-space path, while reach-under and reach-over choices hit the
    rack cabinet, the machine or the floor. The held tool is on by default.
``random_clutter``
    Seeded boxes and cylinders standing on the floor near points of the arm's workspace
    (any arm); obstacles that would touch the arm at ``arm.home`` (within the collision
    checker's clearance) or overlap its fixed base are dropped.
``file``
    The obstacles of an MJCF file, ``scene_file=PATH`` (any arm; base pose, convex
    decomposition of meshes: ``envs/models/scene_file.py``, ``docs/files.md``).

Obstacles are static bodies (children of the world body): contacts among them and with the
floor are never computed, only their contacts with the arm.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from envs.kinematics import Arm
from envs.kinematics.paper_example import RACK_SLOT_OFFSETS_Y, TOOL_ABC_MM, example_poses

from .builders import STEEL, ArmTree, add_part, add_static_body, compile_spec
from .collision import DEFAULT_RESOLUTION, CollisionChecker
from .filter.layout import _GEOM_BOX, _GEOM_CAPSULE, _GEOM_CYLINDER
from .scene_file import file_scene

MACHINE_RGBA = (0.30, 0.55, 0.45, 1.0)
RACK_RGBA = (0.35, 0.40, 0.55, 1.0)
CLUTTER_RGBA = (0.55, 0.50, 0.45, 1.0)

#: Branch index (in ``arm.branch_labels`` order) of the paper's recommended solutions
#: 1.1 and 2.1: shoulder front, elbow up, wrist + at both positions.
RECOMMENDED_BRANCHES = (0, 0)
#: Tool tip to spindle nose at position 2 (m): the last few centimetres of the insertion
#: are the machine's clamping stroke, not the arm's transfer.
SPINDLE_CLEARANCE = 0.03


def default_tool(scene: str) -> bool:
    return scene == "milling_cell"


def milling_cell_poses() -> tuple[np.ndarray, np.ndarray]:
    """The gripper poses (4, 4) at position 1 (rack) and position 2 (spindle), in metres:
    the worked example's points through eq. (3) (``envs.kinematics.paper_example``)."""
    position1, position2 = example_poses()
    return position1, position2


# ----------------------------------------------------------------------------- scenes
def empty(spec: mujoco.MjSpec, arm: Arm, tree: ArmTree) -> mujoco.MjModel:
    return compile_spec(spec)


def _box(body, name, lo, hi, rgba) -> None:
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    add_part(body, name, "box", (hi - lo) / 2, rgba, pos=(hi + lo) / 2)


def milling_cell(spec: mujoco.MjSpec, arm: Arm, tree: ArmTree, *, base_pos=None,
                 base_quat=None, base_rpy=None) -> mujoco.MjModel:
    """Tool rack around position 1 and a C-frame vertical milling machine at position 2.

    Every obstacle is placed relative to the paper's poses, so the cell follows the
    worked example's points rather than the arm's link lengths. The anthropomorphic arm
    of the worked example stands at the cell's origin; any other six-DOF arm stands where
    ``base_pos`` (and a turn about the vertical, ``base_quat``/``base_rpy``) puts its base
    on the cell's floor (the model's world stays the arm's base frame: the cell moves).
    """
    if arm.target != "pose" or arm.dof != 6 or arm.relative or not tree.ee_body:
        raise ValueError(f"the milling cell needs a six-DOF single arm, not {arm.name!r}")
    placed = base_pos is not None or base_quat is not None or base_rpy is not None
    cell = spec.worldbody
    if placed:
        from .scene_file import base_pose

        pose = base_pose(base_pos, base_quat, base_rpy)
        level = abs(pose[2, 3]) < 1e-9 and np.allclose(pose[:3, 2], (0.0, 0.0, 1.0),
                                                        atol=1e-9)
        if not level:
            raise ValueError("the arm's base stands on the cell's floor: base_pos z = 0 "
                             "and a turn about the vertical only")
        inverse = np.eye(4)
        inverse[:3, :3], inverse[:3, 3] = pose[:3, :3].T, -(pose[:3, :3].T @ pose[:3, 3])
        cell = spec.worldbody.add_body()
        cell.name = "cell"
        cell.pos = inverse[:3, 3]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, inverse[:3, :3].ravel())
        cell.quat = quat
    pose1, pose2 = milling_cell_poses()
    o1, tool_axis1 = pose1[:3, 3], pose1[:3, 1]
    o2, tool_axis2 = pose2[:3, 3], pose2[:3, 1]
    if not (np.allclose(tool_axis1, (1, 0, 0)) and np.allclose(tool_axis2, (0, 0, 1))):
        raise RuntimeError("the layout below assumes the paper's tool axes (+X0, then +Z0)")
    tool_length = TOOL_ABC_MM[1] / 1000.0
    x1, y1, z1 = o1

    # Position 1: a cabinet whose top is 0.2 m below the tool and V-block cradles under
    # the tool's far half (clear of the gripper near O), one per rack slot: slot 0 is the
    # paper's position 1, the others continue the rack on the −Y0 side (away from the
    # machine). The slots are where tool_changes tasks fetch and return tools.
    rack = add_static_body(spec, "rack", parent=cell)
    offsets = RACK_SLOT_OFFSETS_Y
    _box(rack, "rack_cabinet", (x1 - 0.12, y1 + min(offsets) - 0.12, 0.0),
         (x1 + 0.48, y1 + max(offsets) + 0.15, z1 - 0.2), RACK_RGBA)
    for k, dy in enumerate(offsets):
        y = y1 + dy
        _box(rack, f"rack_cradle{k}", (x1 + 0.22, y - 0.04, z1 - 0.2),
             (x1 + 0.32, y + 0.04, z1 - 0.045), RACK_RGBA)

    # Position 2: the spindle nose just above the tool tip, the head overhanging from a
    # column behind (−X0), the table and bed below the gripper.
    x2, y2, z2 = o2
    nose = z2 + tool_length + SPINDLE_CLEARANCE
    machine = add_static_body(spec, "mill", parent=cell)
    add_part(machine, "mill_quill", "cylinder", [0.09], MACHINE_RGBA,
             fromto=[x2, y2, nose, x2, y2, nose + 0.40])
    _box(machine, "mill_head", (x2 - 0.65, y2 - 0.20, nose + 0.40), (x2 + 0.17, y2 + 0.20, 2.35),
         MACHINE_RGBA)
    _box(machine, "mill_column", (x2 - 1.00, y2 - 0.35, 0.0), (x2 - 0.65, y2 + 0.35, 2.6),
         MACHINE_RGBA)
    _box(machine, "mill_bed", (x2 - 0.65, y2 - 0.35, 0.0), (x2 + 0.60, y2 + 0.35, z2 - 0.35),
         MACHINE_RGBA)
    _box(machine, "mill_table", (x2 - 0.55, y2 - 0.30, z2 - 0.35), (x2 + 0.50, y2 + 0.30,
         z2 - 0.25), STEEL)
    _box(machine, "mill_vise", (x2 - 0.25, y2 - 0.10, z2 - 0.25), (x2 - 0.05, y2 + 0.10,
         z2 - 0.15), (0.25, 0.25, 0.28, 1.0))
    # The chip guard along the table's −Y0 edge (the robot's side) stops just below the
    # forearm of the elbow-up solutions; an elbow-down forearm comes in lower and hits it.
    _box(machine, "mill_chip_guard", (x2 - 0.55, y2 - 0.32, z2 - 0.25),
         (x2 + 0.50, y2 - 0.30, z2 - 0.03), STEEL)
    return compile_spec(spec)


@dataclass(frozen=True)
class Obstacle:
    """One clutter obstacle standing on the floor: ``kind`` "box" (``half``: half-sizes
    (x, y, z)) or "cylinder" (``half``: radius, radius, half-height), centred at ``pos``."""

    slot: int
    kind: str
    half: tuple[float, float, float]
    pos: tuple[float, float, float]


def _static_arm_discs(model: mujoco.MjModel) -> list[tuple[np.ndarray, float]]:
    """(xy, radius) of every collision geom of the arm's fixed base (its footprint)."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return [
        (data.geom_xpos[g, :2].copy(), float(model.geom_rbound[g]))
        for g in range(model.ngeom)
        if model.geom_bodyid[g] != 0 and model.body_weldid[model.geom_bodyid[g]] == 0
        and model.geom_contype[g]
        and not model.body(model.geom_bodyid[g]).name.startswith("clutter")
    ]


def draw_clutter(arm: Arm, seed: int, base: list[tuple[np.ndarray, float]],
                 n_obstacles: int = 8) -> list[Obstacle]:
    """The obstacles of clutter ``seed``: candidates next to the wrist centres of random
    configurations (numpy ``default_rng(seed)``), those overlapping the fixed base
    (``base`` discs) dropped. Whether one touches the arm at home is the caller's check."""
    rng = np.random.default_rng(seed)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    centres = arm.fk(rng.uniform(lower, upper, size=(n_obstacles, arm.dof)))[:, :3, 3]
    discs = np.array([disc for disc, _ in base], dtype=np.float64).reshape(-1, 2)
    radii = np.array([radius for _, radius in base], dtype=np.float64)
    obstacles = []
    # Python floats: the same IEEE arithmetic as numpy scalars, without their overhead.
    for k, (cx, cy, cz) in enumerate(centres.tolist()):
        h0, h1 = rng.uniform(0.05, 0.2, size=2).tolist()
        # Reach up to somewhere around the sampled wrist centre (never below 0.1 m).
        top = max(0.1, cz + rng.uniform(-0.4, 0.0))
        o0, o1 = rng.normal(scale=0.25, size=2).tolist()
        x, y = cx + o0, cy + o1
        footprint = float(np.hypot(h0, h1))
        if (np.hypot(x - discs[:, 0], y - discs[:, 1]) < footprint + radii).any():
            continue
        pos = (x, y, top / 2)
        if rng.random() < 0.5:
            obstacles.append(Obstacle(k, "box", (h0, h1, top / 2), pos))
        else:
            obstacles.append(Obstacle(k, "cylinder", (h0, h0, top / 2), pos))
    return obstacles


def random_clutter(
    spec: mujoco.MjSpec,
    arm: Arm,
    tree: ArmTree,
    *,
    seed: int | None = 0,
    n_obstacles: int = 8,
    clearance: float = DEFAULT_RESOLUTION,
) -> mujoco.MjModel:
    """Up to ``n_obstacles`` boxes/cylinders near the arm's workspace, seeded by ``seed``.

    Candidates stand on the floor next to the wrist centres of random configurations
    (drawn from ``seed``'s generator); those that would touch the arm at ``arm.home``
    (closer than ``clearance``) or overlap the fixed base are dropped, so fewer than
    ``n_obstacles`` may remain.

    ``seed=None``: a scene whose clutter changes at every episode without a recompile
    (:class:`ClutterSlots`): ``n_obstacles`` obstacle slots, each a primitive box and a
    cylinder (collided as the capsule inside it, as every cylinder here), all parked out
    of reach until :meth:`ClutterSlots.lay` places a drawn clutter.
    """
    if seed is None:
        for k in range(n_obstacles):
            body = add_static_body(spec, f"clutter{k}")
            add_part(body, f"clutter{k}_box", "box", [0.1, 0.1, 0.1], CLUTTER_RGBA,
                     pos=PARKED)
            add_part(body, f"clutter{k}_cylinder", "cylinder", [0.1, 0.2], CLUTTER_RGBA,
                     pos=PARKED)
        return compile_spec(spec, primitive_boxes=lambda name: name.startswith("clutter"))
    base_model = spec.compile()
    obstacles = draw_clutter(arm, seed, _static_arm_discs(base_model), n_obstacles)
    bodies = []
    for obstacle in obstacles:
        body = add_static_body(spec, f"clutter{obstacle.slot}")
        name = f"clutter{obstacle.slot}"
        if obstacle.kind == "box":
            add_part(body, name, "box", list(obstacle.half), CLUTTER_RGBA, pos=list(obstacle.pos))
        else:
            add_part(body, name, "cylinder", [obstacle.half[0], obstacle.half[2]], CLUTTER_RGBA,
                     pos=list(obstacle.pos))
        bodies.append(body)
    model = compile_spec(spec)
    checker = CollisionChecker(model, dof=arm.dof, resolution=clearance)
    touching = {name for c in checker.contacts(arm.home) for name in (c.body1, c.body2)}
    for body in bodies:
        if body.name in touching:
            spec.delete(body)
    return compile_spec(spec) if touching else model


#: Obstacle slots of a per-episode clutter (``random_clutter`` with ``seed=None``).
CLUTTER_SLOTS = 8

#: Where an unused obstacle slot waits: far below the floor, out of every arm's reach
#: (static geoms never collide with each other or the floor).
PARKED = (0.0, 0.0, -100.0)


class ClutterSlots:
    """The obstacle slots of a ``random_clutter`` scene built with ``seed=None``.

    :meth:`lay` writes a drawn clutter into ``MjModel`` copies of it (the env's and its
    collision checker's): positions and sizes of the slots' primitive geoms, with the
    bounding data MuJoCo keeps per geom (``geom_rbound``, ``geom_aabb``) recomputed for the
    new sizes; slots the clutter does not use are parked. ``geoms`` lists every slot geom
    (what a collision checker must re-read afterwards).
    """

    PARTS = ("box", "box_vis", "cylinder", "cylinder_vis")

    def __init__(self, model: mujoco.MjModel, n_obstacles: int) -> None:
        self.n_obstacles = n_obstacles
        #: (n_obstacles, 4) geom ids, columns in ``PARTS`` order.
        self.ids = np.array([[model.geom(f"clutter{k}_{part}").id for part in self.PARTS]
                             for k in range(n_obstacles)])
        self.geoms = self.ids.ravel()
        self._types = model.geom_type[self.geoms]
        self.base = _static_arm_discs(model)

    def lay(self, obstacles: list[Obstacle], *models: mujoco.MjModel) -> None:
        half = np.tile((0.05, 0.05, 0.05), (len(self.geoms), 1))
        pos = np.tile(PARKED, (len(self.geoms), 1))
        for obstacle in obstacles:
            row = 4 * obstacle.slot
            if obstacle.kind == "box":
                parts = (0, 1)
            elif obstacle.half[2] >= obstacle.half[0]:
                parts = (2, 3)
            else:  # a disc: collided as the box around it (as add_part builds it)
                parts = (0, 3)
            for part in parts:
                half[row + part], pos[row + part] = obstacle.half, obstacle.pos
        size, rbound, aabb = _primitive_sizes(self._types, half)
        for model in models:
            model.geom_size[self.geoms] = size
            model.geom_pos[self.geoms] = pos
            model.geom_quat[self.geoms] = (1.0, 0.0, 0.0, 0.0)
            model.geom_rbound[self.geoms] = rbound
            model.geom_aabb[self.geoms] = np.concatenate([np.zeros_like(aabb), aabb], axis=1)


def _primitive_sizes(types: np.ndarray, half: np.ndarray):
    """MuJoCo ``geom_size``, ``geom_rbound`` and ``geom_aabb`` half-extents of primitive
    geoms spanning ``half`` (x, y, z) (a cylinder's: radius, radius, half-height): a box by
    its half-sizes, a cylinder by radius and half-height, a capsule (the collision twin of
    a cylinder) by radius and the half-length of its straight part."""
    radius, height = half[:, 0], half[:, 2]
    size = np.zeros_like(half)
    # Plain ints: comparing an array with MuJoCo's enum objects is ~20 times slower.
    box = types == _GEOM_BOX
    cylinder = types == _GEOM_CYLINDER
    capsule = types == _GEOM_CAPSULE
    if not (box | cylinder | capsule).all():
        raise ValueError("clutter slot geoms must be boxes, cylinders or capsules")
    if np.any(capsule & (height < radius)):
        raise ValueError("a clutter disc lower than it is wide has no capsule slot")
    size[box] = half[box]
    size[cylinder, 0], size[cylinder, 1] = radius[cylinder], height[cylinder]
    size[capsule, 0], size[capsule, 1] = radius[capsule], height[capsule] - radius[capsule]
    rbound = np.where(box, np.linalg.norm(half, axis=1),
                      np.where(cylinder, np.hypot(radius, height), height))
    aabb = np.where(box[:, None], half, np.stack([radius, radius, height], axis=1))
    return size, rbound, aabb


SCENES = {"empty": empty, "milling_cell": milling_cell, "random_clutter": random_clutter}
#: ``scene="file"``: the obstacles of an MJCF file (``scene_file=PATH``; envs/models/scene_file.py).
SCENES["file"] = file_scene
