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
``deburring_cell``
    A part clamped in a fixture on a table in front of the arm, for the ``deburring``
    task (``envs/tasks/deburring.py`` holds its geometry): the part is a rounded-corner
    block (two boxes and four corner cylinders, geoms ``part*``), on a fixture plate with
    two clamps and two locating pins.
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

from ikbranch_gym.envs.jit import njit
from ikbranch_gym.envs.kinematics import Arm
from ikbranch_gym.envs.kinematics.paper_example import (
    RACK_SLOT_OFFSETS_Y,
    TOOL_ABC_MM,
    example_poses,
)

from .builders import (
    STEEL,
    ArmTree,
    add_part,
    add_static_body,
    compile_spec,
    inscribe_cylinders,
)
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
    return compile_spec(spec, collision_shapes=tree.collision_shapes)


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
    return compile_spec(spec, collision_shapes=tree.collision_shapes)


TABLE_TOP = 0.02
FIXTURE_TOP = 0.04
FIXTURE_RGBA = (0.45, 0.45, 0.50, 1.0)
PART_RGBA = (0.75, 0.72, 0.62, 1.0)


def deburring_cell(spec: mujoco.MjSpec, arm: Arm, tree: ArmTree) -> mujoco.MjModel:
    """The part of the deburring task on its fixture (module docstring), in the arm's base
    frame."""
    from ikbranch_gym.envs.tasks.deburring import (
        CORNER_RADIUS,
        PART_CENTRE,
        PART_HALF,
        PART_HEIGHT,
        PART_TOP,
    )

    if arm.target != "pose" or arm.dof != 6 or arm.relative or not tree.ee_body:
        raise ValueError(f"the deburring cell needs a six-DOF single arm, not {arm.name!r}")
    if abs(PART_TOP - PART_HEIGHT - FIXTURE_TOP) > 1e-12:
        raise RuntimeError("the part stands on the fixture plate")
    (cx, cy), (hx, hy), r = PART_CENTRE, PART_HALF, CORNER_RADIUS
    table = add_static_body(spec, "table")
    _box(table, "table", (0.25, -0.30, 0.0), (0.70, 0.30, TABLE_TOP), STEEL)
    fixture = add_static_body(spec, "fixture")
    _box(fixture, "fixture_plate", (cx - hx - 0.03, cy - hy - 0.05, TABLE_TOP),
         (cx + hx + 0.03, cy + hy + 0.05, FIXTURE_TOP), FIXTURE_RGBA)
    for side, name in ((1.0, "clamp_left"), (-1.0, "clamp_right")):  # on the ±y faces
        y0, y1 = sorted((cy + side * hy, cy + side * (hy + 0.03)))
        _box(fixture, name, (cx - 0.02, y0, FIXTURE_TOP), (cx + 0.02, y1, PART_TOP - 0.015),
             FIXTURE_RGBA)
    for k, dy in enumerate((-0.03, 0.03)):  # against the −x face
        add_part(fixture, f"pin{k}", "cylinder", [0.006], STEEL,
                 fromto=[cx - hx - 0.006, cy + dy, FIXTURE_TOP, cx - hx - 0.006, cy + dy,
                         FIXTURE_TOP + 0.03])
    part = add_static_body(spec, "part")
    _box(part, "part", (cx - hx, cy - hy + r, FIXTURE_TOP), (cx + hx, cy + hy - r, PART_TOP),
         PART_RGBA)
    _box(part, "part_1", (cx - hx + r, cy - hy, FIXTURE_TOP), (cx + hx - r, cy + hy, PART_TOP),
         PART_RGBA)
    for k, (sx, sy) in enumerate(((1, 1), (-1, 1), (-1, -1), (1, -1))):
        x, y = cx + sx * (hx - r), cy + sy * (hy - r)
        add_part(part, f"part_{k + 2}", "cylinder", [r], PART_RGBA,
                 fromto=[x, y, FIXTURE_TOP, x, y, PART_TOP])
    return compile_spec(spec, collision_shapes=tree.collision_shapes)


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
    (``base`` discs) dropped. Whether one touches the arm at home is the caller's check.

    The draws, in order: the configurations (``uniform(lower, upper, size=(n, dof))``),
    then per candidate its half-sizes (``uniform(0.05, 0.2, size=2)``), its top
    (``uniform(-0.4, 0.0)``), its offset (``normal(scale=0.25, size=2)``) and, unless it
    is dropped, its kind (``random()``); the candidates' draws run in one compiled call
    (:func:`_candidates`: numba draws from a NumPy ``Generator`` exactly as NumPy does).
    """
    rng = np.random.default_rng(seed)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    centres = arm.positions(rng.uniform(lower, upper, size=(n_obstacles, arm.dof)))
    flat: list[float] = []  # (x, y, radius) of every disc
    for disc, radius in base:
        flat += disc.tolist() if type(disc) is np.ndarray else list(disc)
        flat.append(radius)
    discs = np.array(flat, dtype=np.float64).reshape(-1, 3)
    rows = np.empty((n_obstacles, 7))
    count = _candidates(rng, np.ascontiguousarray(centres), discs, rows)
    obstacles = []
    for k, box, h0, h1, z, x, y in rows[:count].tolist():
        if box:
            obstacles.append(Obstacle(int(k), "box", (h0, h1, z), (x, y, z)))
        else:
            obstacles.append(Obstacle(int(k), "cylinder", (h0, h0, z), (x, y, z)))
    return obstacles


@njit
def _candidates(rng, centres, discs, rows):
    """The candidates of :func:`draw_clutter` next to the wrist ``centres`` (n, 3), their
    draws from ``rng``, those overlapping a disc (x, y, radius) of ``discs`` dropped: rows
    (slot, box, h0, h1, half-height, x, y) of the kept ones, in slot order; returns their
    number."""
    count = 0
    for k in range(centres.shape[0]):
        cx, cy, cz = centres[k, 0], centres[k, 1], centres[k, 2]
        h0 = rng.uniform(0.05, 0.2)
        h1 = rng.uniform(0.05, 0.2)
        # Reach up to somewhere around the sampled wrist centre (never below 0.1 m).
        top = cz + rng.uniform(-0.4, 0.0)
        if not top > 0.1:  # Python's max(0.1, top)
            top = 0.1
        x = cx + rng.normal(0.0, 0.25)
        y = cy + rng.normal(0.0, 0.25)
        footprint = np.hypot(h0, h1)  # the C library's hypot, as numpy's
        dropped = False
        for d in range(discs.shape[0]):
            if np.hypot(x - discs[d, 0], y - discs[d, 1]) < footprint + discs[d, 2]:
                dropped = True
                break
        if dropped:
            continue
        box = rng.random() < 0.5
        rows[count, 0], rows[count, 1] = k, 1.0 if box else 0.0
        rows[count, 2], rows[count, 3], rows[count, 4] = h0, h1, top / 2
        rows[count, 5], rows[count, 6] = x, y
        count += 1
    return count


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
    cylinder (collided as the cylinder, or as the capsule inside it in the earlier models),
    all parked out of reach until :meth:`ClutterSlots.lay` places a drawn clutter.
    """
    if seed is None:
        for k in range(n_obstacles):
            body = add_static_body(spec, f"clutter{k}")
            add_part(body, f"clutter{k}_box", "box", [0.1, 0.1, 0.1], CLUTTER_RGBA,
                     pos=PARKED)
            add_part(body, f"clutter{k}_cylinder", "cylinder", [0.1, 0.2], CLUTTER_RGBA,
                     pos=PARKED)
        return compile_spec(spec, primitive_boxes=lambda name: name.startswith("clutter"),
                            collision_shapes=tree.collision_shapes)
    if tree.collision_shapes == "inscribed":
        inscribe_cylinders(spec)  # the base's footprint as the earlier models drew it
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
    model = compile_spec(spec, collision_shapes=tree.collision_shapes)
    checker = CollisionChecker(model, dof=arm.dof, resolution=clearance)
    touching = checker.contact_bodies(arm.home)
    for body in bodies:
        if body.name in touching:
            spec.delete(body)
    return compile_spec(spec, collision_shapes=tree.collision_shapes) if touching else model


#: Obstacle slots of a per-episode clutter (``random_clutter`` with ``seed=None``).
CLUTTER_SLOTS = 8

#: Where an unused obstacle slot waits: far below the floor, out of every arm's reach
#: (static geoms never collide with each other or the floor).
PARKED = (0.0, 0.0, -100.0)
_PARKED_X, _PARKED_Y, _PARKED_Z = PARKED


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
        self._primitive = bool(np.isin(self._types,
                                       (_GEOM_BOX, _GEOM_CYLINDER, _GEOM_CAPSULE)).all())
        self.base = _static_arm_discs(model)

    def lay(self, obstacles: list[Obstacle], *models: mujoco.MjModel) -> None:
        if not self._primitive:
            raise ValueError("clutter slot geoms must be boxes, cylinders or capsules")
        # Rows (slot, parts, half x, y, z, pos x, y, z); parts: 0 the box geoms (box and
        # its visual), 1 the cylinder geoms, 2 a disc where the earlier models collide
        # cylinders as capsules (collided as the box around it: the box and the visual
        # cylinder).
        inscribed = self._types[2] == _GEOM_CAPSULE
        flat: list[float] = []
        for obstacle in obstacles:
            half = obstacle.half
            parts = (0 if obstacle.kind == "box"
                     else 2 if inscribed and half[2] < half[0] else 1)
            flat += (obstacle.slot, parts, *half, *obstacle.pos)
        rows = np.array(flat, dtype=np.float64).reshape(-1, 8)
        n_geoms = len(self.geoms)
        size, pos, rbound = np.empty((n_geoms, 3)), np.empty((n_geoms, 3)), np.empty(n_geoms)
        aabb = np.empty((n_geoms, 6))
        status = _slot_values(self._types, rows, size, pos, rbound, aabb)
        if status == 1:
            raise IndexError(f"an obstacle slot outside 0..{self.n_obstacles - 1}")
        if status == 2:
            raise ValueError("a clutter disc lower than it is wide has no capsule slot")
        for model in models:
            _write_slots(self.geoms, size, pos, rbound, aabb, model.geom_size, model.geom_pos,
                         model.geom_quat, model.geom_rbound, model.geom_aabb)


@njit
def _slot_values(types, rows, size, pos, rbound, aabb):
    """MuJoCo ``geom_size``, ``geom_pos``, ``geom_rbound`` and ``geom_aabb`` of the slot
    geoms (``types``, four a slot in ``ClutterSlots.PARTS`` order) standing the obstacles
    ``rows`` (see ``ClutterSlots.lay``), the others parked: a box by its half-sizes, a
    cylinder by radius and half-height, a capsule (the collision twin of a cylinder) by
    radius and the half-length of its straight part. Returns 0, else 1 for a slot out of
    range, 2 for a capsule lower than it is wide (then no model is written)."""
    n_geoms = types.shape[0]
    half = np.empty((n_geoms, 3))
    for g in range(n_geoms):
        half[g, 0] = half[g, 1] = half[g, 2] = 0.05
        pos[g, 0], pos[g, 1], pos[g, 2] = _PARKED_X, _PARKED_Y, _PARKED_Z
    for r in range(rows.shape[0]):
        slot = rows[r, 0]
        if not (0 <= slot and 4 * slot + 4 <= n_geoms):
            return 1
        row = 4 * int(slot)
        parts = rows[r, 1]
        first, second = (0, 1) if parts == 0 else (2, 3) if parts == 1 else (0, 3)
        for g in (row + first, row + second):
            for c in range(3):
                half[g, c] = rows[r, 2 + c]
                pos[g, c] = rows[r, 5 + c]
    for g in range(n_geoms):
        if types[g] == _GEOM_CAPSULE and half[g, 2] < half[g, 0]:
            return 2
    for g in range(n_geoms):
        radius, height = half[g, 0], half[g, 2]
        aabb[g, 0] = aabb[g, 1] = aabb[g, 2] = 0.0
        aabb[g, 3], aabb[g, 4], aabb[g, 5] = radius, radius, height
        size[g, 2] = 0.0
        if types[g] == _GEOM_BOX:
            size[g, 0], size[g, 1], size[g, 2] = radius, half[g, 1], height
            aabb[g, 4] = half[g, 1]
            # numpy's norm(half, axis=1) of these rows: (x² + y²) + z², then the root.
            rbound[g] = np.sqrt((radius * radius + half[g, 1] * half[g, 1])
                                + height * height)
        elif types[g] == _GEOM_CYLINDER:
            size[g, 0], size[g, 1] = radius, height
            rbound[g] = np.hypot(radius, height)  # libm's, as numpy's
        else:  # capsule
            size[g, 0], size[g, 1] = radius, height - radius
            rbound[g] = height
    return 0


@njit
def _write_slots(geoms, size, pos, rbound, aabb, geom_size, geom_pos, geom_quat, geom_rbound,
                 geom_aabb):
    """Write the slot geoms' values (:func:`_slot_values`) into a model's arrays."""
    for i in range(geoms.shape[0]):
        g = geoms[i]
        for c in range(3):
            geom_size[g, c] = size[i, c]
            geom_pos[g, c] = pos[i, c]
        geom_quat[g, 0] = 1.0
        geom_quat[g, 1] = geom_quat[g, 2] = geom_quat[g, 3] = 0.0
        geom_rbound[g] = rbound[i]
        for c in range(6):
            geom_aabb[g, c] = aabb[i, c]


SCENES = {"empty": empty, "milling_cell": milling_cell, "random_clutter": random_clutter,
          "deburring_cell": deburring_cell}
#: ``scene="file"``: the obstacles of an MJCF file (``scene_file=PATH``; envs/models/scene_file.py).
SCENES["file"] = file_scene
