"""The collision shapes stand for the drawn ones: every drawn part lies inside its
collision twin, and no explicit exclusion hides an overlap of drawn parts (coal measures
the drawn shapes of the pairs excluded beyond a joint's own two sides)."""

from __future__ import annotations

import hashlib

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from ikbranch_gym.envs import CURRENT_IDS
from ikbranch_gym.envs.models.builders import COLLISION_GROUP, VISUAL_GROUP
from ikbranch_gym.envs.models.independent import Measure, hidden_body_pairs
from ikbranch_gym.envs.seeds import held_out

_G = mujoco.mjtGeom
#: Points of a drawn shape may lie this far (m) outside its collision shape: a box collided
#: as a mesh has float32 vertices (rounding at 1 m is 6e-8 m).
TOLERANCE = 1e-7


def _circle(n: int = 48) -> np.ndarray:
    angle = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.stack([np.cos(angle), np.sin(angle)], axis=1)


def _sphere(n: int = 200) -> np.ndarray:
    """Fibonacci points on the unit sphere."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def surface_points(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Points on the surface of geom ``g`` (its rims, edges and corners among them), in the
    geom's frame."""
    kind, size = model.geom_type[g], model.geom_size[g]
    if kind == _G.mjGEOM_SPHERE:
        return size[0] * _sphere()
    if kind == _G.mjGEOM_CAPSULE:
        ball, end = size[0] * _sphere(), np.array([0.0, 0.0, size[1]])
        return np.concatenate([ball + end, ball - end])
    if kind == _G.mjGEOM_CYLINDER:
        rim = size[0] * _circle()
        out = []
        for z in np.linspace(-size[1], size[1], 9):
            out.append(np.column_stack([rim, np.full(len(rim), z)]))
            out.append(np.column_stack([0.5 * rim, np.full(len(rim), z)]))
        return np.concatenate(out)
    if kind == _G.mjGEOM_BOX:
        grid = np.array(np.meshgrid(*[np.linspace(-1, 1, 5)] * 3)).reshape(3, -1).T
        on_surface = np.abs(grid).max(axis=1) == 1
        return grid[on_surface] * size
    if kind == _G.mjGEOM_MESH:
        mesh = model.geom_dataid[g]
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        return model.mesh_vert[start:start + count].astype(float)
    raise AssertionError(f"no surface sampler for geom type {kind}")


def outside(model: mujoco.MjModel, g: int, points: np.ndarray) -> np.ndarray:
    """How far (m, ≤ 0 inside) each point (geom ``g``'s frame) lies outside geom ``g``."""
    kind, size = model.geom_type[g], model.geom_size[g]
    if kind == _G.mjGEOM_SPHERE:
        return np.linalg.norm(points, axis=1) - size[0]
    if kind == _G.mjGEOM_CAPSULE:
        axial = np.clip(points[:, 2], -size[1], size[1])
        return np.linalg.norm(points - np.column_stack(
            [np.zeros((len(points), 2)), axial]), axis=1) - size[0]
    if kind == _G.mjGEOM_CYLINDER:
        return np.maximum(np.hypot(points[:, 0], points[:, 1]) - size[0],
                          np.abs(points[:, 2]) - size[1])
    if kind == _G.mjGEOM_BOX:
        return (np.abs(points) - size[:3]).max(axis=1)
    if kind == _G.mjGEOM_MESH:
        hull = ConvexHull(surface_points(model, g))
        return (points @ hull.equations[:, :3].T + hull.equations[:, 3]).max(axis=1)
    raise AssertionError(f"no inside test for geom type {kind}")


def containment_gaps(model: mujoco.MjModel) -> dict[str, float]:
    """For every drawn geom ``<name>_vis``: how far (m) its surface reaches outside its
    collision twin ``<name>`` (a missing twin is an error)."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    gaps = {}
    for g in np.flatnonzero(model.geom_group == VISUAL_GROUP):
        name = model.geom(g).name
        assert name.endswith("_vis"), name
        twin = model.geom(name[: -len("_vis")]).id
        assert model.geom_group[twin] == COLLISION_GROUP and model.geom_contype[twin]
        assert model.geom_bodyid[twin] == model.geom_bodyid[g]
        world = data.geom_xpos[g] + surface_points(model, g) @ data.geom_xmat[g].reshape(3, 3).T
        local = (world - data.geom_xpos[twin]) @ data.geom_xmat[twin].reshape(3, 3)
        gaps[name[: -len("_vis")]] = float(outside(model, twin, local).max())
    return gaps


@pytest.mark.parametrize("env_id", CURRENT_IDS)
def test_every_drawn_part_lies_inside_its_collision_shape(env_id):
    env = gym.make(env_id, **held_out(env_id))
    env.reset(seed=0)  # a clutter laid into the obstacle slots
    gaps = containment_gaps(env.unwrapped.model)
    assert len(gaps) >= 5
    assert max(gaps.values()) <= TOLERANCE, {k: v for k, v in gaps.items() if v > TOLERANCE}


def test_the_earlier_models_collide_cylinders_inside_the_drawn_ones():
    # The check above can fail: the earlier generation's cylinders stick out of the
    # capsules inside them, by their rims (the held tool, the spindle's quill).
    env = gym.make("IKBranch/ToolTransfer-v1")
    env.reset(seed=0)
    gaps = containment_gaps(env.unwrapped.model)
    assert gaps["tool"] > 0.01
    assert gaps["mill_quill"] > 0.03


def _hidden_overlap(env_id: str, n: int) -> float:
    """The least signed distance (m) coal measures between the drawn geoms of the body
    pairs excluded beyond a joint's own two sides, over ``n`` random configurations in the
    joint limits (inf when there are none)."""
    env = gym.make(env_id, **held_out(env_id))
    env.reset(seed=0)
    probe = Measure(env)
    if not len(probe.excluded):
        return np.inf
    limits = env.unwrapped.arm.joint_limits
    rng = np.random.default_rng(7)
    return min(float(probe.lower_bounds(q, probe.excluded).min())
               for q in rng.uniform(limits[:, 0], limits[:, 1], size=(n, len(limits))))


@pytest.mark.parametrize("env_id", CURRENT_IDS)
def test_no_exclusion_hides_an_overlap_of_drawn_parts(env_id):
    # Only the UR wrist keeps exclusions beyond a joint's own two sides; their drawn parts
    # never overlap anywhere in the joint limits.
    model = gym.make(env_id, **held_out(env_id)).unwrapped.model
    hidden = {tuple(sorted((model.body(a).name, model.body(b).name)))
              for a, b in hidden_body_pairs(model)}
    if env_id.startswith("IKBranch/UR5e"):
        assert hidden == {("link_elbow", "link_wrist2"), ("link_wrist1", "link_wrist3")}
    else:
        assert hidden == set()
    assert _hidden_overlap(env_id, 3000) >= 0.0


def test_the_earlier_wrist_exclusions_hid_overlaps():
    # The check above can fail: the earlier Anthropomorphic wrist's roll housing and flange
    # overlap at random configurations.
    assert _hidden_overlap("IKBranch/Anthropomorphic-v2", 300) < -0.01


#: SHA-256 (first 16 hex digits) of the compiled model of every id of the earlier
#: generations (geom types, sizes, poses and contact bits, exclusions, body frames, mesh
#: vertices; after ``reset(seed=0)`` with two waypoints), recorded from the code before
#: the drawn generation existed.
EARLIER_MODELS = {
    "IKBranch/Cartesian-v1": "ce20e5b616a3a405",
    "IKBranch/Cylindrical-v1": "636dfa60baf98e13",
    "IKBranch/Spherical-v1": "2db42145bf45fcfb",
    "IKBranch/Anthropomorphic-v1": "55de1750953f5084",
    "IKBranch/Cylindrical4-v1": "80934b38c1154ea1",
    "IKBranch/ToolTransfer-v0": "d93d1d4b6902fbb9",
    "IKBranch/DualRRPRPP-v0": "5d9064c0b437830e",
    "IKBranch/DualRRRPPP-v0": "326900de02e01723",
    "IKBranch/DualPPRPRR-v0": "038721eecba1da53",
    "IKBranch/RodMechanism-v1": "a9e340db13921160",
    "IKBranch/Cartesian-v2": "4215eabe5fa68ca5",
    "IKBranch/Cylindrical-v2": "05c0695881e37ae0",
    "IKBranch/Spherical-v2": "77d750ae0feb04d1",
    "IKBranch/Anthropomorphic-v2": "d1db5d82df98d45f",
    "IKBranch/Cylindrical4-v2": "4a580aa0e9ac82e5",
    "IKBranch/ToolTransfer-v1": "d93d1d4b6902fbb9",
    "IKBranch/DualRRPRPP-v1": "5d9064c0b437830e",
    "IKBranch/DualRRRPPP-v1": "326900de02e01723",
    "IKBranch/DualPPRPRR-v1": "038721eecba1da53",
    "IKBranch/RodMechanism-v2": "a9e340db13921160",
    "IKBranch/KukaKR6-v0": "78206115efc63a7e",
    "IKBranch/UR5e-v0": "ce8a1cf167e32fc8",
    "IKBranch/IRB4600ToolTransfer-v0": "b763971bb91590d0",
    "IKBranch/IRB2600Screwing-v0": "6a7c11748b9134d9",
}


@pytest.mark.regression
@pytest.mark.parametrize("env_id", sorted(EARLIER_MODELS))
def test_the_earlier_ids_keep_their_models(env_id):
    env = gym.make(env_id, n_waypoints=2)
    env.reset(seed=0)
    model = env.unwrapped.model
    digest = hashlib.sha256()
    for array in (model.geom_type, model.geom_size, model.geom_pos, model.geom_quat,
                  model.geom_contype, np.sort(model.exclude_signature), model.body_pos,
                  model.body_quat, model.mesh_vert):
        digest.update(np.ascontiguousarray(array).tobytes())
    assert digest.hexdigest()[:16] == EARLIER_MODELS[env_id]


def test_an_unknown_generation_of_collision_shapes_is_refused():
    with pytest.raises(ValueError, match="collision_shapes must be one of drawn, inscribed"):
        gym.make("IKBranch/Cartesian-v3", collision_shapes="capsules")
