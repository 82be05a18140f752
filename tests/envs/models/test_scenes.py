"""The per-episode clutter's kernels (envs/models/scenes.py) give the numbers of the numpy
code they replaced, bit for bit: the drawn obstacles (against a frozen copy of the numpy
``draw_clutter``) and the values ``lay`` writes into a model (against a frozen copy of the
numpy ``lay``)."""

from __future__ import annotations

import copy

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import build_model
from ikbranch_gym.envs.models.filter.layout import _GEOM_BOX, _GEOM_CAPSULE, _GEOM_CYLINDER
from ikbranch_gym.envs.models.scenes import (
    CLUTTER_SLOTS,
    PARKED,
    ClutterSlots,
    Obstacle,
    draw_clutter,
)

FIELDS = ("geom_size", "geom_pos", "geom_quat", "geom_rbound", "geom_aabb")


# ------------------------------------------------- the numpy code the kernels replaced
def numpy_draw_clutter(arm, seed, base, n_obstacles=8):
    rng = np.random.default_rng(seed)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    centres = arm.fk(rng.uniform(lower, upper, size=(n_obstacles, arm.dof)))[:, :3, 3]
    discs = np.array([disc for disc, _ in base], dtype=np.float64).reshape(-1, 2)
    radii = np.array([radius for _, radius in base], dtype=np.float64)
    obstacles = []
    for k, (cx, cy, cz) in enumerate(centres.tolist()):
        h0, h1 = rng.uniform(0.05, 0.2, size=2).tolist()
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


def numpy_lay(types, geoms, obstacles, *models):
    half = np.tile((0.05, 0.05, 0.05), (len(geoms), 1))
    pos = np.tile(PARKED, (len(geoms), 1))
    for obstacle in obstacles:
        row = 4 * obstacle.slot
        if obstacle.kind == "box":
            parts = (0, 1)
        elif obstacle.half[2] >= obstacle.half[0] or types[2] != _GEOM_CAPSULE:
            parts = (2, 3)  # a disc is a box only where cylinders collide as capsules
        else:
            parts = (0, 3)
        for part in parts:
            half[row + part], pos[row + part] = obstacle.half, obstacle.pos
    radius, height = half[:, 0], half[:, 2]
    size = np.zeros_like(half)
    box, cylinder, capsule = types == _GEOM_BOX, types == _GEOM_CYLINDER, types == _GEOM_CAPSULE
    size[box] = half[box]
    size[cylinder, 0], size[cylinder, 1] = radius[cylinder], height[cylinder]
    size[capsule, 0], size[capsule, 1] = radius[capsule], height[capsule] - radius[capsule]
    rbound = np.where(box, np.linalg.norm(half, axis=1),
                      np.where(cylinder, np.hypot(radius, height), height))
    aabb = np.where(box[:, None], half, np.stack([radius, radius, height], axis=1))
    for model in models:
        model.geom_size[geoms] = size
        model.geom_pos[geoms] = pos
        model.geom_quat[geoms] = (1.0, 0.0, 0.0, 0.0)
        model.geom_rbound[geoms] = rbound
        model.geom_aabb[geoms] = np.concatenate([np.zeros_like(aabb), aabb], axis=1)


def _bits(obstacles):
    """Everything of the obstacles, floats as their bytes."""
    return [(o.slot, o.kind, np.array(o.half).tobytes(), np.array(o.pos).tobytes())
            for o in obstacles]


# ---------------------------------------------------------------------------- tests
ARMS = ("anthropomorphic", "cylindrical", "cartesian", "spherical", "kuka_kr6_r700", "ur5e",
        "abb_irb4600")


@pytest.mark.parametrize("arm_name", ARMS)
def test_draw_clutter_is_the_numpy_draw(arm_name):
    arm = make_arm(arm_name)
    clutter = ClutterSlots(build_model(arm_name, "random_clutter", seed=None), CLUTTER_SLOTS)
    seeds = [*range(100), *np.random.default_rng(1).integers(0, 2_000_000, 100).tolist()]
    drawn = 0
    for seed in seeds:
        obstacles = draw_clutter(arm, seed, clutter.base, CLUTTER_SLOTS)
        assert _bits(obstacles) == _bits(numpy_draw_clutter(arm, seed, clutter.base)), seed
        drawn += len(obstacles)
    assert drawn > 0
    # Other counts, numpy integer seeds and bases.
    base = [(np.array([0.3, -0.2]), 0.25), ((0.0, 0.0), 0.1)]
    for seed in (np.int64(5), np.uint32(77), 2**40 + 3, [1, 2, 3]):
        for n, discs in ((3, clutter.base), (12, base), (8, [])):
            assert (_bits(draw_clutter(arm, seed, discs, n))
                    == _bits(numpy_draw_clutter(arm, seed, discs, n)))


def _random_obstacles(rng, n_slots):
    """Obstacles on distinct random slots (boxes, cylinders, discs) in random order, and
    sometimes a slot laid twice (the later one stands)."""
    slots = rng.permutation(n_slots)[: rng.integers(0, n_slots + 1)]
    obstacles = []
    for slot in slots.tolist():
        half = rng.uniform(0.05, 0.2, size=2).tolist()
        z = float(rng.uniform(0.05, 0.9))
        pos = (*rng.normal(size=2).tolist(), z)
        kind = "box" if rng.random() < 0.5 else "cylinder"
        obstacles.append(Obstacle(slot, kind, (half[0], half[1] if kind == "box" else half[0],
                                               z), pos))
    if obstacles and rng.random() < 0.2:
        obstacles.append(Obstacle(obstacles[0].slot, "cylinder", (0.3, 0.3, 0.1),
                                  (0.1, 0.2, 0.1)))
    return obstacles


@pytest.mark.parametrize("collision_shapes", ["drawn", "inscribed"])
@pytest.mark.parametrize("arm_name", ("anthropomorphic", "ur5e"))
def test_lay_writes_what_the_numpy_lay_wrote(arm_name, collision_shapes):
    model = build_model(arm_name, "random_clutter", seed=None,
                        collision_shapes=collision_shapes)
    clutter = ClutterSlots(model, CLUTTER_SLOTS)
    ours, theirs = copy.copy(model), copy.copy(model)
    twin = copy.copy(model)
    arm = make_arm(arm_name)
    rng = np.random.default_rng(0)
    for trial in range(600):
        if trial % 2:
            obstacles = _random_obstacles(rng, CLUTTER_SLOTS)
        else:
            obstacles = draw_clutter(arm, trial, clutter.base, CLUTTER_SLOTS)
        clutter.lay(obstacles, ours, twin)
        numpy_lay(clutter._types, clutter.geoms, obstacles, theirs)
        for name in FIELDS:
            assert getattr(ours, name).tobytes() == getattr(theirs, name).tobytes(), name
            assert getattr(twin, name).tobytes() == getattr(theirs, name).tobytes(), name
    # Every other geom is left alone.
    untouched = np.setdiff1d(np.arange(model.ngeom), clutter.geoms)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(ours, name)[untouched],
                                      getattr(model, name)[untouched])


def test_lay_refuses_a_slot_out_of_range():
    model = build_model("anthropomorphic", "random_clutter", seed=None)
    clutter = ClutterSlots(model, CLUTTER_SLOTS)
    before = model.geom_pos.copy()
    with pytest.raises(IndexError):
        clutter.lay([Obstacle(CLUTTER_SLOTS, "box", (0.1, 0.1, 0.1), (0.0, 0.0, 0.1))], model)
    np.testing.assert_array_equal(model.geom_pos, before)
    assert isinstance(model, mujoco.MjModel)
