"""The MuJoCo trees reproduce the kinematics exactly; every scene compiles and steps."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import ARM_NAMES, make_arm
from ikbranch_gym.envs.models import (
    TREE_BUILDERS,
    build_arm_model,
    build_model,
    register_tree_builder,
)
from ikbranch_gym.envs.tools import Tool
from tests.envs.models.conftest import SINGLE_ARM_NAMES, TWO_ARM_NAMES, scene_cases

N_CONFIGS = 1000


def _random_q(arm, n, seed=20240611):
    rng = np.random.default_rng(seed)
    return rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(n, arm.dof))


def _site_poses(model, arm, q):
    data = mujoco.MjData(model)
    site = model.site("ee").id
    position, rotation = np.empty((len(q), 3)), np.empty((len(q), 3, 3))
    for i, row in enumerate(q):
        data.qpos[: arm.dof] = row
        mujoco.mj_kinematics(model, data)
        position[i] = data.site_xpos[site]
        rotation[i] = data.site_xmat[site].reshape(3, 3)
    return position, rotation


@pytest.mark.parametrize("arm_name", SINGLE_ARM_NAMES)
def test_ee_site_is_the_fk_frame(arm_name):
    arm = make_arm(arm_name)
    model = build_model(arm_name)
    q = _random_q(arm, N_CONFIGS)
    expected = arm.fk(q)
    position, rotation = _site_poses(model, arm, q)
    np.testing.assert_allclose(position, expected[:, :3, 3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(rotation, expected[:, :3, :3], rtol=0, atol=1e-9)


def _relative_site_poses(model, arm, q):
    """Pose (N, 4, 4) of site ``link4`` expressed in site ``link3``."""
    data = mujoco.MjData(model)
    site3, site4 = model.site("link3").id, model.site("link4").id
    poses = np.tile(np.eye(4), (len(q), 1, 1))
    for i, row in enumerate(q):
        data.qpos[: arm.dof] = row
        mujoco.mj_kinematics(model, data)
        r3 = data.site_xmat[site3].reshape(3, 3)
        poses[i, :3, :3] = r3.T @ data.site_xmat[site4].reshape(3, 3)
        poses[i, :3, 3] = r3.T @ (data.site_xpos[site4] - data.site_xpos[site3])
    return poses


@pytest.mark.parametrize("arm_name", TWO_ARM_NAMES)
def test_two_arm_relative_pose_of_link4_in_link3_is_fk(arm_name):
    arm = make_arm(arm_name)
    model = build_model(arm_name)
    q = _random_q(arm, N_CONFIGS)
    np.testing.assert_allclose(_relative_site_poses(model, arm, q), arm.fk(q), rtol=0, atol=1e-9)


@pytest.mark.parametrize("arm_name", ARM_NAMES)
def test_sites_follow_the_contract(arm_name):
    model = build_model(arm_name)
    sites = {model.site(s).name for s in range(model.nsite)}
    expected = {"link3", "link4"} if arm_name in TWO_ARM_NAMES else {"ee"}
    assert sites == expected


@pytest.mark.parametrize(
    ("arm_name", "params"),
    [
        ("dual_rrp_rpp", {"a0": 0.4, "l1": 0.6, "b0": 0.25}),
        ("dual_rrr_ppp", {"h": 0.9, "l1": 0.3, "l2": 0.4, "l3": 0.25, "b0": 1.0}),
        ("dual_ppr_prr", {"l1": 1.4, "l3": 0.5, "l4": 0.25, "l5": 0.6}),
        ("rod_mechanism", {"lp_prime": 0.3, "b": 0.45, "a": 0.2, "gamma": 1.2, "psi": 1.4}),
    ],
)
def test_non_default_parameters_follow_the_new_arms(arm_name, params):
    arm = make_arm(arm_name, **params)
    model = build_arm_model(arm)
    q = _random_q(arm, 50, seed=7)
    if arm_name in TWO_ARM_NAMES:
        np.testing.assert_allclose(_relative_site_poses(model, arm, q), arm.fk(q), atol=1e-9)
    else:
        position, rotation = _site_poses(model, arm, q)
        np.testing.assert_allclose(position, arm.fk(q)[:, :3, 3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(rotation, arm.fk(q)[:, :3, :3], rtol=0, atol=1e-9)


def test_non_default_parameters_follow_the_arm():
    arm = make_arm("anthropomorphic", l1=1.1, l2=0.8, l3=0.7)
    model = build_arm_model(arm, tool=True)
    q = np.random.default_rng(7).uniform(
        arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(50, arm.dof)
    )
    position, rotation = _site_poses(model, arm, q)
    np.testing.assert_allclose(position, arm.fk(q)[:, :3, 3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(rotation, arm.fk(q)[:, :3, :3], rtol=0, atol=1e-9)


@pytest.mark.parametrize("arm_name", ARM_NAMES)
def test_joints_are_the_arms_in_order_with_its_limits(arm_name):
    arm = make_arm(arm_name)
    model = build_model(arm_name)
    assert model.nq == arm.dof
    for index, (name, kind) in enumerate(zip(arm.joint_names, arm.joint_types, strict=True)):
        joint = model.joint(name)
        assert model.jnt_qposadr[joint.id] == index
        assert joint.type[0] == (
            mujoco.mjtJoint.mjJNT_HINGE if kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE
        )
        assert model.jnt_limited[joint.id]
        # Radians: a degree-compiled spec would have scaled hinge ranges by π/180.
        np.testing.assert_allclose(model.jnt_range[joint.id], arm.joint_limits[index], atol=1e-12)


def test_prismatic_qpos_is_the_displacement():
    arm = make_arm("cartesian")
    model = build_model("cartesian")
    data = mujoco.MjData(model)
    data.qpos[:] = arm.home
    data.qpos[:3] = (0.3, -0.2, 0.7)
    mujoco.mj_kinematics(model, data)
    np.testing.assert_allclose(data.body("link_s3").xpos, (0.3, -0.2, 0.7), atol=1e-12)


@pytest.mark.parametrize(("arm_name", "scene"), scene_cases())
def test_scene_compiles_and_steps_without_warnings(arm_name, scene):
    arm = make_arm(arm_name)
    model = build_model(arm_name, scene)
    data = mujoco.MjData(model)
    data.qpos[: arm.dof] = arm.home
    for _ in range(20):
        mujoco.mj_step(model, data)
    assert all(data.warning[i].number == 0 for i in range(len(data.warning)))
    assert np.all(np.isfinite(data.qpos))


@pytest.mark.parametrize("arm_name", ARM_NAMES)
def test_visual_and_collision_geoms_are_separate(arm_name):
    model = build_model(arm_name, tool=True)
    names = [model.geom(g).name for g in range(model.ngeom)]
    for g, name in enumerate(names):
        if name.endswith("_vis"):
            assert model.geom_contype[g] == model.geom_conaffinity[g] == 0
            assert name[: -len("_vis")] in names
    assert model.geom("tool").contype[0] != 0
    assert model.body("tool").id > 0


@pytest.mark.parametrize("arm_name", ["cylindrical4", "rod_mechanism", "dual_rrp_rpp"])
def test_milling_cell_refuses_what_is_not_a_six_dof_single_arm(arm_name):
    # A two-arm system's fk is relative (one arm's link seen from the other's): no tool
    # in the cell's world to carry.
    with pytest.raises(ValueError, match="six-DOF single arm"):
        build_model(arm_name, "milling_cell")


@pytest.mark.parametrize("arm_name", ["cartesian", "kuka_kr6_r700"])
def test_milling_cell_takes_other_six_dof_arms(arm_name):
    model = build_model(arm_name, "milling_cell", base_pos=(-1.0, 0.0, 0.0))
    assert model.nq == 6


def test_unknown_names_are_rejected():
    with pytest.raises(ValueError, match="scene"):
        build_model("cartesian", "moon")
    with pytest.raises(ValueError, match="already registered"):
        register_tree_builder("cartesian")(TREE_BUILDERS["cartesian"])


def test_random_clutter_is_seeded():
    def layout(seed):
        model = build_model("spherical", "random_clutter", seed=seed)
        return np.concatenate([model.geom_pos.ravel(), model.geom_size.ravel()])

    empty = build_model("spherical")
    first = layout(3)
    assert np.array_equal(first, layout(3))
    assert not np.array_equal(first, layout(4))
    assert build_model("spherical", "random_clutter", seed=3).ngeom > empty.ngeom


# --------------------------------------------------- industrial arms in every scene
INDUSTRIAL_ARMS = ("kuka_kr6_r700", "abb_irb2400", "abb_irb2600", "abb_irb4600", "ur5e", "ur10e")
EXAMPLES = Path(__file__).resolve().parents[3] / "examples"
#: scene case -> (scene, scene kwargs, name prefix of the bodies the scene adds).
INDUSTRIAL_SCENES = {
    "empty": ("empty", {}, None),
    "random_clutter": ("random_clutter", {"seed": 5}, "clutter"),
    # seed=None: per-episode clutter slots, parked until laid.
    "random_clutter_slots": ("random_clutter", {"seed": None}, "clutter"),
    # Any six-DOF arm stands where base_pos/base_rpy put it; the cell moves, the model's
    # world stays the arm's base frame.
    "milling_cell": ("milling_cell", {"base_pos": (-1.0, 0.3, 0.0), "base_rpy": (0.0, 0.0, 0.4)},
                     "mill"),
    "file_milling_cell": ("file", {"scene_file": EXAMPLES / "milling_cell.xml"}, "scene/"),
    # Base at the file's arm_base site (moved and turned 5°); decompose="never" writes no
    # CoACD cache next to the example (the obstacles' shape does not matter here).
    "file_welding_cell": ("file", {"scene_file": EXAMPLES / "welding_cell.xml",
                                   "decompose": "never"}, "scene/"),
}
#: A two-part tool whose TCP is moved and turned off the flange axis (every component of
#: the TCP's pose non-trivial).
OFFSET_TOOL = {
    "parts": [{"shape": "box", "size": [0.08, 0.06, 0.12]},
              {"shape": "cylinder", "size": [0.015, 0.25],
               "offset": {"pos": [0.0, 0.02, 0.12], "rpy": [-0.6, 0.0, 0.0]}}],
    "tcp": {"pos": [0.01, 0.16, 0.32], "rpy": [-0.6, 0.1, 0.3]},
}


def _beyond_half_turn(arm, n, seed):
    """n configurations inside the limits with every joint whose limits pass ±π drawn
    from the part of its range beyond ±π (KUKA's A2 −190°…−180°, A4 ±(180°…185°))."""
    rng = np.random.default_rng(seed)
    q = _random_q(arm, n, seed=seed + 1)
    for joint, (lower, upper) in enumerate(arm.joint_limits):
        parts = [(lo, hi) for lo, hi in ((lower, -np.pi), (np.pi, upper)) if lo < hi]
        if not parts:
            continue
        for i in range(n):
            lo, hi = parts[rng.integers(len(parts))]
            q[i, joint] = rng.uniform(lo, hi)
    return q


def _site_frames(model, dof, q, names):
    """{site: (N, 4, 4) world pose} for the configurations q (N, dof)."""
    data = mujoco.MjData(model)
    ids = {name: model.site(name).id for name in names}
    out = {name: np.tile(np.eye(4), (len(q), 1, 1)) for name in names}
    for i, row in enumerate(q):
        data.qpos[:dof] = row
        mujoco.mj_kinematics(model, data)
        for name, site in ids.items():
            out[name][i, :3, :3] = data.site_xmat[site].reshape(3, 3)
            out[name][i, :3, 3] = data.site_xpos[site]
    return out


@pytest.mark.parametrize("scene_case", INDUSTRIAL_SCENES)
@pytest.mark.parametrize("arm_name", INDUSTRIAL_ARMS)
def test_industrial_ee_and_tcp_sites_are_fk_in_every_scene(arm_name, scene_case):
    arm = make_arm(arm_name)
    scene, kwargs, prefix = INDUSTRIAL_SCENES[scene_case]
    q = np.concatenate([_random_q(arm, 300, seed=12), _beyond_half_turn(arm, 60, seed=13)])
    # Turns: every joint whose limits pass ±π is sampled beyond it (no wrapping).
    wide = np.abs(arm.joint_limits).max(axis=1) > np.pi
    assert wide.any() and np.all((np.abs(q[:, wide]) > np.pi).sum(axis=0) >= 30)
    expected = arm.fk(q)
    tool = Tool.from_spec(OFFSET_TOOL)
    for held in (None, tool):  # the scene's default (the milling cell's built-in tool), ours
        model = build_arm_model(arm, scene, tool=held, **kwargs)
        assert model.nq == arm.dof
        if prefix is not None:
            bodies = [model.body(b).name for b in range(model.nbody)]
            assert any(name.startswith(prefix) for name in bodies), bodies
        sites = ["ee"] if held is None else ["ee", "tcp"]
        frames = _site_frames(model, arm.dof, q, sites)
        np.testing.assert_allclose(frames["ee"], expected, rtol=0, atol=1e-9)
        if held is not None:
            np.testing.assert_allclose(frames["tcp"], held.tcp_poses(expected), rtol=0,
                                       atol=1e-9)
