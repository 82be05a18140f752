"""``build_model``: an arm's kinematic tree plus a scene, compiled to an ``MjModel``."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from ikbranch_gym.envs.kinematics import Arm, make_arm
from ikbranch_gym.envs.tools import Tool, ToolPart

from .builders import (
    COLLISION_BIT,
    TREE_BUILDERS,
    ArmTree,
    check_collision_shapes,
    exclude,
)
from .scenes import SCENES, default_tool


def arm_spec(arm: Arm, *, tool: bool = False,
             collision_shapes: str = "drawn") -> tuple[mujoco.MjSpec, ArmTree]:
    """A fresh ``MjSpec`` holding the floor, lights and ``arm``'s tree (no obstacles),
    with collision shapes of the generation ``collision_shapes`` (``envs.models.builders``)."""
    check_collision_shapes(collision_shapes)
    try:
        builder = TREE_BUILDERS[arm.name]
    except KeyError:
        raise ValueError(
            f"no MuJoCo tree builder for arm {arm.name!r}; registered: "
            f"{', '.join(TREE_BUILDERS)}"
        ) from None
    spec = mujoco.MjSpec()
    spec.modelname = arm.name
    spec.compiler.degree = False  # every angle below, and every joint range, is in radians
    spec.compiler.autolimits = True
    spec.option.timestep = 0.002
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960
    spec.visual.headlight.ambient = np.array([0.35, 0.35, 0.35])
    spec.visual.headlight.diffuse = np.array([0.5, 0.5, 0.5])

    texture = spec.add_texture()
    texture.name = "grid"
    texture.type = mujoco.mjtTexture.mjTEXTURE_2D
    texture.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
    texture.rgb1 = np.array([0.80, 0.82, 0.85])
    texture.rgb2 = np.array([0.70, 0.72, 0.76])
    texture.width = texture.height = 512
    material = spec.add_material()
    material.name = "floor"
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "grid"
    material.texrepeat = np.array([8.0, 8.0])
    floor = spec.worldbody.add_geom()
    floor.name = "floor"
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = np.array([0.0, 0.0, 0.05])  # infinite plane
    floor.material = "floor"
    floor.contype = floor.conaffinity = COLLISION_BIT
    light = spec.worldbody.add_light()
    light.name = "sun"
    light.pos = np.array([2.0, -2.0, 6.0])
    light.dir = np.array([-0.3, 0.3, -1.0])
    light.diffuse = np.array([0.6, 0.6, 0.6])
    light.castshadow = True

    tree = builder(spec, arm, tool, collision_shapes)
    tree.collision_shapes = collision_shapes
    exclude(spec, "world", "base")  # the base stands on the floor
    return spec, tree


def build_arm_model(
    arm: Arm, scene: str = "empty", *, tool: bool | Tool | None = None,
    collision_shapes: str = "drawn", **scene_kwargs: Any
) -> mujoco.MjModel:
    """Compile ``arm`` (any registered ``Arm`` instance, any parameters) in ``scene``.

    ``collision_shapes``: ``"drawn"`` (every collision shape is the drawn shape) or
    ``"inscribed"`` (the earlier models: see ``envs.models.builders``).

    ``tool``: True adds the built-in held tool (a 0.35 m cylinder along the tool axis from
    the fk frame, body ``tool``); by default it is on in scenes that are about carrying a
    tool (the milling cell); a :class:`~envs.tools.Tool` adds that tool instead (its solids
    in body ``tool`` on the fk frame, a site ``tcp`` at its TCP). ``scene_kwargs`` go to
    the scene builder (e.g. ``seed`` for ``random_clutter``).
    """
    try:
        scene_builder = SCENES[scene]
    except KeyError:
        raise ValueError(f"unknown scene {scene!r}; choose one of {', '.join(SCENES)}") from None
    if tool is None:
        tool = default_tool(scene)
    spec, tree = arm_spec(arm, tool=tool is True, collision_shapes=collision_shapes)
    if isinstance(tool, Tool):
        add_tool(spec, tree, tool)
    model = scene_builder(spec, arm, tree, **scene_kwargs)
    check_joint_order(model, arm)
    if isinstance(tool, Tool):
        _check_tool_meshes(model, tool)
    return model


def _check_tool_meshes(model: mujoco.MjModel, tool: Tool) -> None:
    """``ValueError`` for a tool mesh larger than any tool: a mesh written in millimetres
    (MuJoCo reads mesh files in metres)."""
    from ikbranch_gym.envs.tools import MAX_TOOL_LENGTH

    from .scene_file import mesh_size

    for i, part in enumerate(tool.parts):
        if part.mesh is None:
            continue
        geom = model.geom("tool" if i == 0 else f"tool_{i}")
        size = mesh_size(model, int(model.geom_dataid[geom.id]))
        if size > MAX_TOOL_LENGTH:
            raise ValueError(f"tool mesh {part.mesh} spans {size:.3g} m, more than "
                             f"{MAX_TOOL_LENGTH:g} m: is it in millimetres? Tool meshes "
                             "are read in metres")


def add_tool(spec: mujoco.MjSpec, tree: ArmTree, tool: Tool) -> None:
    """``tool``'s solids (visual and collision twins of each part, ``envs/tools.py``) in a
    body ``tool`` welded to the fk frame (the site ``ee``), and a site ``tcp`` at its TCP.
    Part 0 is the geom ``tool``, part i the geom ``tool_<i>``. The tool meets every body
    but the fk frame's and its parent (MuJoCo's rule for a welded body); in the earlier
    models (``collision_shapes="inscribed"``) it also passed the two bodies before the fk
    frame's (mounted through them)."""
    if not tree.ee_body:
        raise ValueError("a tool needs an arm with an fk frame (site ee); two-arm systems "
                         "have none")
    ee = spec.site("ee")
    holder = spec.body(tree.ee_body).add_body()
    holder.name = "tool"
    holder.pos, holder.quat = np.array(ee.pos), np.array(ee.quat)
    for index, part in enumerate(tool.parts):
        _add_tool_part(spec, holder, part, "tool" if index == 0 else f"tool_{index}")
    site = holder.add_site()
    site.name = "tcp"
    site.pos = tool.tcp[:3, 3]
    tcp_quat = np.zeros(4)
    mujoco.mju_mat2Quat(tcp_quat, tool.tcp[:3, :3].ravel())
    site.quat = tcp_quat
    site.size = np.array([0.02, 0.0, 0.0])
    tree.tool_body = holder.name
    if tree.collision_shapes == "drawn":
        return
    body, mounts = spec.body(tree.ee_body), []
    for _ in range(2):
        parent = body.parent
        if parent is None or parent.name in ("world", "base"):
            break
        mounts.append(parent.name)
        body = parent
    for name in mounts:
        exclude(spec, name, "tool")


def _add_tool_part(spec: mujoco.MjSpec, holder: mujoco.MjsBody, part: ToolPart,
                   name: str) -> None:
    """One solid of a tool in ``holder`` (the fk frame): geoms ``name`` (collision) and
    ``name_vis``, placed at the part's offset."""
    from .builders import TOOL_RGBA, add_part

    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, part.offset[:3, :3].ravel())
    if part.shape == "mesh":
        if part.mesh is None:  # ToolPart.from_spec gives every mesh part its file
            raise ValueError(f"tool part {name}: shape 'mesh' needs a mesh file")
        mesh = spec.add_mesh()
        mesh.name = f"{name}_mesh"
        mesh.file = str(part.mesh.resolve())
        for visual in (True, False):
            geom = holder.add_geom()
            geom.name = f"{name}_vis" if visual else name
            geom.type, geom.meshname = mujoco.mjtGeom.mjGEOM_MESH, mesh.name
            geom.pos, geom.quat = part.offset[:3, 3], quat
            geom.contype = geom.conaffinity = 0 if visual else 1
            geom.group = 2 if visual else 3
            geom.rgba = TOOL_RGBA
    elif part.shape == "cylinder":
        radius, length = part.size
        start, end = part.offset[:3, 3], part.offset[:3, 3] + length * part.offset[:3, 2]
        add_part(holder, name, "cylinder", [radius], TOOL_RGBA,
                 fromto=np.concatenate([start, end]))
    else:
        half = np.array(part.size) / 2
        centre = part.offset[:3, 3] + half[2] * part.offset[:3, 2]
        add_part(holder, name, "box", half, TOOL_RGBA, pos=centre, quat=quat)


def build_model(
    arm_name: str,
    scene: str = "empty",
    *,
    arm_params: dict[str, Any] | None = None,
    **kwargs: Any,
) -> mujoco.MjModel:
    """``build_arm_model(make_arm(arm_name, **arm_params), scene, **kwargs)``."""
    return build_arm_model(make_arm(arm_name, **(arm_params or {})), scene, **kwargs)


def check_joint_order(model: mujoco.MjModel, arm: Arm) -> None:
    """``RuntimeError`` unless qpos[:dof] are the arm's joints in kinematics order."""
    for index, (name, kind) in enumerate(zip(arm.joint_names, arm.joint_types, strict=True)):
        joint = model.joint(name)
        expected = (
            mujoco.mjtJoint.mjJNT_HINGE if kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE
        )
        if model.jnt_qposadr[joint.id] != index or model.jnt_type[joint.id] != expected:
            raise RuntimeError(f"{arm.name}: joint {name} is not qpos[{index}] of type {kind}")
