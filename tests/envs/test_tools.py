"""Tools (``envs/tools.py``): parsing, the TCP mapping, and the solid in the MuJoCo model."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from ikbranch_gym.envs.ik_branch_env import IKBranchEnv
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import build_arm_model
from ikbranch_gym.envs.tools import Tool

TORCH = {"shape": "cylinder", "size": [0.02, 0.3],
         "offset": {"pos": [0.0, 0.01, 0.0], "rpy": [0.3, 0.0, 0.0]},
         "tcp": {"pos": [0.0, 0.1, 0.28], "rpy": [0.3, 0.0, 0.0]}}


@pytest.mark.parametrize(("spec", "match"), [
    ({"shape": "sphere", "size": [1.0]}, "shape"),
    ({"shape": "cylinder", "size": [0.02]}, "size must be 2"),
    ({"shape": "box", "size": [0.1, 0.1, 0.0]}, "positive"),
    ({"shape": "cylinder", "size": [0.02, 0.3], "colour": "red"}, "unknown keys"),
    ({"shape": "cylinder", "size": [0.02, 0.3], "tcp": {"pos": [0, 0, 1], "quat": [1, 0, 0, 0.1]}},
     "norm"),
    ({"shape": "cylinder", "size": [0.02, 0.3], "tcp": {"quat": [1, 0, 0, 0], "rpy": [0, 0, 0]}},
     "not both"),
    ({"shape": "cylinder", "size": [0.02, math.nan]}, "finite"),
    ({"shape": "mesh"}, "needs 'mesh'"),
    ({"shape": "mesh", "mesh": "no/such/torch.stl"}, "no such file"),
    ({"parts": []}, "non-empty list"),
    ({"parts": {"shape": "box"}}, "non-empty list"),
    ({"parts": [{"shape": "box", "size": [0.1, 0.1, 0.1]}], "shape": "box"}, "not both"),
    ({"parts": [{"shape": "box", "size": [0.1, 0.1, 0.1], "tcp": {}}]},
     r"parts\[0\]: unknown keys \['tcp'\] \(the tcp is the whole tool's"),
    ({"parts": [{"shape": "box", "size": [0.1, 0.1, 0.1]}, {"shape": "cone"}]},
     r"tool parts\[1\] shape must be one of"),
    ({"parts": [{"shape": "box", "size": [0.1, 0.1, 0.1]}, "box"]},
     r"tool parts\[1\] must be a dict"),
    ({"parts": [{"shape": "mesh", "mesh": 3}]}, r"parts\[0\] mesh must be the path"),
    ({"parts": [{"shape": "box", "size": [0.1, 0.1, 0.1]}], "colour": "red"}, "unknown keys"),
    ({"shape": "cylinder", "size": [25, 350]},
     r"size \[25\.0, 350\.0\] is more than 5 m: is it in millimetres"),
    ({"shape": "cylinder", "size": [0.025, 0.35], "tcp": {"pos": [0, 0, 370]}},
     r"tool tcp\.pos \[0, 0, 370\] lies more than 5 m from the flange: is it in millimetres"),
    ({"parts": [{"shape": "box", "size": [0.1, 0.1, 0.1], "offset": {"pos": [0, 0, 200]}}]},
     r"offset\.pos \[0, 0, 200\] lies more than 5 m"),
])
def test_malformed_tools_are_refused(spec, match):
    with pytest.raises(ValueError, match=match):
        Tool.from_spec(spec)


def test_rpy_and_quaternion_give_the_same_frame():
    # A quarter turn about z, then a half turn about x: written both ways.
    by_rpy = Tool.from_spec({"shape": "box", "size": [0.1, 0.1, 0.1],
                             "tcp": {"rpy": [math.pi, 0.0, math.pi / 2]}}).tcp
    h = math.sqrt(0.5)  # q = qz(90°)·qx(180°) = (h, 0, 0, h)·(0, 1, 0, 0)
    by_quat = Tool.from_spec({"shape": "box", "size": [0.1, 0.1, 0.1],
                              "tcp": {"quat": [0.0, h, h, 0.0]}}).tcp
    expected = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    np.testing.assert_allclose(by_rpy[:3, :3], expected, atol=1e-15)
    np.testing.assert_allclose(by_quat[:3, :3], expected, atol=1e-15)


def test_flange_poses_put_the_tcp_on_the_pose():
    tool = Tool.from_spec(TORCH)
    rng = np.random.default_rng(0)
    env = IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="random")
    poses = env.arm.fk(rng.uniform(*env.arm.joint_limits.T, size=(50, 6)))
    np.testing.assert_allclose(tool.tcp_poses(tool.flange_poses(poses)), poses, atol=1e-14)


@pytest.mark.parametrize("arm_name", ["kuka_kr6_r700", "ur5e", "anthropomorphic"])
def test_the_model_carries_the_tool_at_the_fk_frame(arm_name):
    env = IKBranchEnv(arm=arm_name, scene="empty", task="random", tool=TORCH)
    tool, model = env.tool, env.model
    data = mujoco.MjData(model)
    tcp = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tcp")
    solid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "tool")
    assert model.geom_contype[solid] == 1
    rng = np.random.default_rng(1)
    for q in rng.uniform(*env.arm.joint_limits.T, size=(20, env.arm.dof)):
        data.qpos[: env.arm.dof] = q
        mujoco.mj_kinematics(model, data)
        flange = env.arm.fk(q)
        expected = tool.tcp_poses(flange)
        np.testing.assert_allclose(data.site_xpos[tcp], expected[:3, 3], atol=1e-9)
        np.testing.assert_allclose(data.site_xmat[tcp].reshape(3, 3), expected[:3, :3],
                                   atol=1e-9)
        # The cylinder runs 0.3 m along the offset frame's z from the offset's origin.
        axis = flange[:3, :3] @ tool.offset[:3, 2]
        centre = flange[:3, :3] @ tool.offset[:3, 3] + flange[:3, 3] + 0.15 * axis
        np.testing.assert_allclose(data.geom_xpos[solid], centre, atol=1e-9)
        # (fromto may point the geom's z either way along the axis: a cylinder is even.)
        np.testing.assert_allclose(abs(data.geom_xmat[solid].reshape(3, 3)[:, 2] @ axis), 1.0,
                                   atol=1e-9)


def test_a_tool_collides_where_the_bare_arm_does_not():
    # Pointing the flange at the floor from just above it: only the tool reaches it.
    bare = IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="random")
    armed = IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="random",
                        tool={"shape": "cylinder", "size": [0.02, 0.5]})
    down = np.array([[1.0, 0.0, 0.0, 0.5], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.15],
                     [0.0, 0.0, 0.0, 1.0]])
    q, valid = bare.arm.ik(down)
    assert valid.any()
    q = q[valid]
    assert not bare.checker.collides(q).any()
    assert armed.checker.collides(q).all()


#: A gripper (box) holding a long rod that sticks out sideways from its end: part 1 alone
#: reaches where the one-solid tool of part 0 cannot.
GRIPPER_AND_ROD = {
    "parts": [{"shape": "box", "size": [0.08, 0.08, 0.1]},
              {"shape": "cylinder", "size": [0.015, 0.4],
               "offset": {"pos": [0.0, 0.0, 0.1], "rpy": [0.0, math.pi / 2, 0.0]}}],
    "tcp": {"pos": [0.4, 0.0, 0.1]},
}


def test_a_tool_of_several_parts_is_each_part_in_the_model():
    tool = Tool.from_spec(GRIPPER_AND_ROD)
    assert [part.shape for part in tool.parts] == ["box", "cylinder"]
    assert tool.shape == "box" and tool.size == (0.08, 0.08, 0.1)  # part 0's
    env = IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="random", tool=GRIPPER_AND_ROD)
    model, data = env.model, mujoco.MjData(env.model)
    gripper = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "tool")
    rod = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "tool_1")
    assert gripper >= 0 and rod >= 0 and model.geom_contype[rod] == 1
    assert model.geom_bodyid[gripper] == model.geom_bodyid[rod]  # one body: never a pair
    q = np.array([0.3, -1.2, 0.8, 0.4, 0.9, -0.7])
    data.qpos[:6] = q
    mujoco.mj_kinematics(model, data)
    flange = env.arm.fk(q)
    # The rod: 0.4 m along the flange's x (its offset frame's z), starting 0.1 m out on z.
    start = flange[:3, :3] @ np.array([0.0, 0.0, 0.1]) + flange[:3, 3]
    np.testing.assert_allclose(data.geom_xpos[rod], start + 0.2 * flange[:3, 0], atol=1e-9)
    # The box: its centre half its length (0.05 m) along the flange's z.
    np.testing.assert_allclose(data.geom_xpos[gripper],
                               flange[:3, :3] @ np.array([0.0, 0.0, 0.05]) + flange[:3, 3],
                               atol=1e-9)
    tcp = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tcp")
    np.testing.assert_allclose(data.site_xpos[tcp], tool.tcp_poses(flange)[:3, 3], atol=1e-9)


def test_the_second_part_of_a_tool_collides_on_its_own():
    # The flange pointing down 0.25 m over the floor, tilted about its y so that the rod
    # (along the flange's x) dips: its end at 0.25 − 0.1·cos(tilt) − 0.4·sin(tilt) < 0,
    # the gripper's lowest corner still ~0.14 m up.
    one_part = IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="random",
                           tool={"parts": GRIPPER_AND_ROD["parts"][:1]})
    two_parts = IKBranchEnv(arm="kuka_kr6_r700", scene="empty", task="random",
                            tool=GRIPPER_AND_ROD)
    c, s = math.cos(-0.45), math.sin(-0.45)
    down = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    tilted = down @ np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = tilted, [0.45, 0.0, 0.25]
    q, valid = one_part.arm.ik(pose)
    q = q[valid]
    assert len(q)
    assert not one_part.checker.collides(q).any()
    assert two_parts.checker.collides(q).all()


def test_a_tool_mesh_in_millimetres_gets_a_hint(tmp_path):
    # A torch drawn 150 mm long, written as the CAD exported it: 150 units, read as metres.
    mesh = tmp_path / "torch.obj"
    mesh.write_text("v 0 0 0\nv 20 0 0\nv 0 20 0\nv 0 0 150\n"
                    "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n")
    tool = Tool.from_spec({"shape": "mesh", "mesh": str(mesh)})
    with pytest.raises(ValueError, match=r"torch\.obj spans 15\d m, more than 5 m: is it in "
                                         "millimetres"):
        build_arm_model(make_arm("kuka_kr6_r700"), "empty", tool=tool)
    metres = tmp_path / "torch_m.obj"
    metres.write_text(mesh.read_text().replace(" 20 ", " 0.02 ").replace(" 150", " 0.15"))
    build_arm_model(make_arm("kuka_kr6_r700"), "empty",
                    tool=Tool.from_spec({"shape": "mesh", "mesh": str(metres)}))
