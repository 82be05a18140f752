"""Scene files (envs/models/scene_file.py): merge, base pose, naming, errors, and the convex
decomposition of non-convex meshes with its cache.

Expected geometry comes from the test itself (the U channel's solid, rotations built from
elementary matrices, the built-in milling cell), never from the module under test.
"""

from __future__ import annotations

import math
import re
import struct
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import (
    CollisionChecker,
    build_arm_model,
    build_model,
    milling_cell_poses,
)
from ikbranch_gym.envs.models import scene_file as sf
from ikbranch_gym.envs.models.builders import compile_spec
from ikbranch_gym.envs.models.scene_file import SceneFileError, add_scene_file, load_scene_file

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "milling_cell.xml"
ARM = make_arm("anthropomorphic")
#: Quick CoACD settings for the small test meshes (the U channel decomposes in ~0.2 s).
FAST = {"threshold": 0.1, "mcts_iterations": 50, "resolution": 500}


# ------------------------------------------------------------------------------- helpers
def rot(axis: str, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return {
        "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


def quat_of(rotation: np.ndarray) -> np.ndarray:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, rotation.ravel())
    return q


def u_channel(width=0.3, height=0.2, wall=0.05, floor=0.05, depth=0.2):
    """A closed, outward-oriented U channel: profile in x–z, extruded along y.

    Solid = [0, w]×[0, d]×[0, floor] ∪ the walls [0, wall] and [w − wall, w] up to ``height``;
    the gap is x ∈ (wall, w − wall), z > floor."""
    w, h = width, height
    profile = [(0, 0), (w, 0), (w, floor), (w, h), (w - wall, h), (w - wall, floor),
               (wall, floor), (wall, h), (0, h), (0, floor)]
    caps = [(0, 1, 2), (0, 2, 5), (0, 5, 6), (0, 6, 9), (5, 2, 3), (5, 3, 4), (9, 6, 7),
            (9, 7, 8)]
    n = len(profile)
    vertices = [(x, 0.0, z) for x, z in profile] + [(x, depth, z) for x, z in profile]
    faces = []
    for a, b, c in caps:
        faces += [(a, b, c), (a + n, c + n, b + n)]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j + n, j), (i, i + n, j + n)]
    return np.array(vertices, dtype=float), np.array(faces)


def u_solid_contains(points, width=0.3, height=0.2, wall=0.05, floor=0.05, depth=0.2):
    x, y, z = np.moveaxis(np.asarray(points), -1, 0)
    inside = (x >= 0) & (x <= width) & (y >= 0) & (y <= depth) & (z >= 0) & (z <= height)
    return inside & ((z <= floor) | (x <= wall) | (x >= width - wall))


def write_obj(path: Path, vertices, faces) -> None:
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def write_binary_stl(path: Path, vertices, faces) -> None:
    data = bytearray(b"\0" * 80 + struct.pack("<I", len(faces)))
    for face in faces:
        a, b, c = (vertices[i] for i in face)
        normal = np.cross(b - a, c - a)
        normal /= np.linalg.norm(normal)
        data += struct.pack("<12fH", *normal, *a, *b, *c, 0)
    path.write_bytes(bytes(data))


def write_scene(directory: Path, body: str, name: str = "cell.xml", assets: str = "",
                head: str = "") -> Path:
    path = directory / name
    path.write_text(textwrap.dedent(f"""\
        <mujoco>
          {head}
          <asset>{assets}</asset>
          <worldbody>
        {textwrap.indent(textwrap.dedent(body), "    ")}
          </worldbody>
        </mujoco>
        """))
    return path


def probe_model(scene) -> mujoco.MjModel:
    """A sphere (r = 10 mm) on x, y, z slides, no floor, plus the scene's obstacles."""
    spec = mujoco.MjSpec()
    spec.compiler.degree = False
    body = spec.worldbody.add_body()
    body.name = "probe"
    for k, axis in enumerate(np.eye(3)):
        joint = body.add_joint()
        joint.name, joint.type, joint.axis = f"s{k}", mujoco.mjtJoint.mjJNT_SLIDE, axis
        joint.range = np.array([-5.0, 5.0])
    geom = body.add_geom()
    geom.name, geom.size = "ball", np.array([0.01, 0, 0])
    add_scene_file(spec, scene, floor=False)
    return compile_spec(spec)


def scene_geoms(model) -> dict[str, int]:
    return {model.geom(g).name: g for g in range(model.ngeom)
            if model.geom(g).name.startswith("scene/")}


@pytest.fixture
def count_coacd(monkeypatch):
    calls = []
    real = sf.run_coacd

    def counting(vertices, faces, options):
        calls.append(dict(options))
        return real(vertices, faces, options)

    monkeypatch.setattr(sf, "run_coacd", counting)
    return calls


# ------------------------------------------------------- the milling cell as a scene file
@pytest.fixture(scope="module")
def cells():
    builtin = CollisionChecker(build_model("anthropomorphic", "milling_cell"), dof=6)
    from_file = CollisionChecker(
        build_arm_model(ARM, "file", scene_file=EXAMPLE, tool=True), dof=6)
    return builtin, from_file


def _strip(name: str) -> str:
    return name.removeprefix("scene/")


def test_milling_cell_file_collides_like_the_builtin_cell(cells):
    builtin, from_file = cells
    rng = np.random.default_rng(0)
    q = rng.uniform(ARM.joint_limits[:, 0], ARM.joint_limits[:, 1], size=(3000, 6))
    expected = builtin.collides(q)
    assert 0.1 < expected.mean() < 0.9
    assert np.array_equal(from_file.collides(q), expected)
    assert np.array_equal(from_file.n_contacts(q[:300]), builtin.n_contacts(q[:300]))
    for qq in q[expected][:40]:  # the same pairs, under the prefixed names
        pairs = {tuple(sorted((_strip(c.geom1), _strip(c.geom2)))) for c in builtin.contacts(qq)}
        found = {tuple(sorted((_strip(c.geom1), _strip(c.geom2)))) for c in from_file.contacts(qq)}
        assert found == pairs


def test_milling_cell_file_transfers_like_the_builtin_cell(cells):
    builtin, from_file = cells
    (q1, ok1), (q2, ok2) = (ARM.ik(pose) for pose in milling_cell_poses())
    assert ok1.all() and ok2.all()
    a = builtin.check_paths(q1[:, None], q2[None, :])
    b = from_file.check_paths(q1[:, None], q2[None, :])
    assert np.array_equal(a[0], b[0])
    assert np.array_equal(a[1], b[1], equal_nan=True)
    assert not b[0][0, 0]  # the paper's 1.1 -> 2.1 is free in the file's cell too


def test_milling_cell_file_names_and_groups():
    model = build_arm_model(ARM, "file", scene_file=EXAMPLE, tool=True)
    names = scene_geoms(model)
    for obstacle in ("rack_cabinet", "rack_cradle2", "mill_quill", "mill_chip_guard"):
        vis, col = names[f"scene/{obstacle}_vis"], names[f"scene/{obstacle}"]
        assert model.geom_contype[vis] == model.geom_conaffinity[vis] == 0
        assert model.geom_group[vis] == 2 and model.geom_group[col] == 3
        assert model.geom_contype[col] == model.geom_conaffinity[col] == 1
        assert model.body(model.geom_bodyid[col]).name == f"scene/{obstacle.split('_')[0]}"
        assert model.body_weldid[model.geom_bodyid[col]] == 0  # static
    # A cylinder is collided as drawn (contype = conaffinity = 0 in a file makes a geom a
    # visual twin only: test_meshdir_and_decompose_modes).
    for twin in ("scene/mill_quill", "scene/mill_quill_vis"):
        assert model.geom_type[names[twin]] == mujoco.mjtGeom.mjGEOM_CYLINDER
    # colours from the file's default classes
    np.testing.assert_allclose(model.geom_rgba[names["scene/rack_cabinet_vis"]],
                               (0.35, 0.40, 0.55, 1), atol=1e-7)
    np.testing.assert_allclose(model.geom_rgba[names["scene/mill_vise_vis"]],
                               (0.25, 0.25, 0.28, 1), atol=1e-7)
    assert model.geom("floor").id >= 0 and model.site("scene/cell").id >= 0


def _text(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def _moved_cell(directory: Path, pose: np.ndarray) -> Path:
    """The example cell with everything inside a body at ``pose`` (the cell frame moved),
    the arm's base site at ``pose`` too, and the floor as a plane in that body."""
    tree = ET.parse(EXAMPLE)
    world = tree.getroot().find("worldbody")
    children = list(world)
    pos, quat = _text(pose[:3, 3]), _text(quat_of(pose[:3, :3]))
    wrapper = ET.SubElement(world, "body", name="moved", pos=pos, quat=quat)
    for child in children:
        world.remove(child)
        if child.tag != "site":
            wrapper.append(child)
    ET.SubElement(wrapper, "geom", name="ground", type="plane", size="0 0 0.05")
    ET.SubElement(world, "site", name="arm_base", pos=pos, quat=quat)
    path = directory / "moved_cell.xml"
    tree.write(path)
    return path


def test_base_pose_from_the_site_keeps_the_arm_in_the_moved_cell(tmp_path, cells):
    builtin, _ = cells
    pose = np.eye(4)
    pose[:3, :3] = rot("z", 2.1) @ rot("x", 0.4) @ rot("y", -0.3)
    pose[:3, 3] = (3.0, -1.5, 0.7)
    path = _moved_cell(tmp_path, pose)
    model = build_arm_model(ARM, "file", scene_file=path, tool=True, floor=False)
    assert "floor" not in {model.geom(g).name for g in range(model.ngeom)}
    moved = CollisionChecker(model, dof=6)
    rng = np.random.default_rng(1)
    q = rng.uniform(ARM.joint_limits[:, 0], ARM.joint_limits[:, 1], size=(1500, 6))
    assert np.array_equal(moved.collides(q), builtin.collides(q))
    # the cell site: inv(pose) in the base frame
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    site = model.site("scene/cell").id
    np.testing.assert_allclose(data.site_xmat[site].reshape(3, 3), pose[:3, :3].T, atol=1e-12)
    np.testing.assert_allclose(data.site_xpos[site], -pose[:3, :3].T @ pose[:3, 3], atol=1e-12)
    scene = load_scene_file(path)
    np.testing.assert_allclose(scene.base_pose, pose, atol=1e-12)
    target = milling_cell_poses()[0]
    np.testing.assert_allclose(scene.cell_to_base(pose @ target), target, atol=1e-12)


def _geom_world(model) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return {name: (data.geom_xpos[g].copy(), data.geom_xmat[g].copy())
            for name, g in scene_geoms(model).items()}


def test_base_pose_options_equal_the_site(tmp_path):
    pose = np.eye(4)
    pose[:3, :3] = rot("z", 0.7)
    pose[:3, 3] = (0.5, 0.25, 0.0)
    with_site = _geom_world(build_arm_model(ARM, "file", scene_file=_moved_cell(tmp_path, pose),
                                            floor=False))
    # the same cell without the site, the base given as options
    plain = tmp_path / "plain.xml"
    text = (tmp_path / "moved_cell.xml").read_text()
    plain.write_text(re.sub(r"<site name=\"arm_base\"[^>]*/>", "", text))
    by_quat = _geom_world(build_arm_model(
        ARM, "file", scene_file=plain, floor=False, base_pos=pose[:3, 3],
        base_quat=(math.cos(0.35), 0, 0, math.sin(0.35))))
    by_rpy = _geom_world(build_arm_model(
        ARM, "file", scene_file=plain, floor=False, base_pos=pose[:3, 3], base_rpy=(0, 0, 0.7)))
    assert with_site.keys() == by_quat.keys() == by_rpy.keys()
    for name, (pos, mat) in with_site.items():
        for other in (by_quat, by_rpy):
            np.testing.assert_allclose(other[name][0], pos, atol=1e-12, err_msg=name)
            np.testing.assert_allclose(other[name][1], mat, atol=1e-12, err_msg=name)


def test_rpy_convention_is_fixed_axes_xyz(tmp_path):
    path = write_scene(tmp_path, '<geom name="b" type="sphere" size="0.1" pos="1 2 3"/>')
    roll, pitch, yaw = 0.3, -0.5, 1.2
    model = build_arm_model(ARM, "file", scene_file=path, base_rpy=(roll, pitch, yaw),
                            base_pos=(0.1, 0.2, 0.3))
    cell = rot("z", yaw) @ rot("y", pitch) @ rot("x", roll)  # R = Rz·Ry·Rx (URDF rpy)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    np.testing.assert_allclose(data.geom_xpos[model.geom("scene/b").id],
                               cell.T @ (np.array([1, 2, 3]) - (0.1, 0.2, 0.3)), atol=1e-12)
    # the floor is the cell's z = 0 plane: its normal is the cell's z axis, in base axes
    floor = model.geom("floor").id
    np.testing.assert_allclose(data.geom_xmat[floor].reshape(3, 3)[:, 2], cell.T[:, 2],
                               atol=1e-12)
    np.testing.assert_allclose(data.geom_xpos[floor], -cell.T @ (0.1, 0.2, 0.3), atol=1e-12)


def test_floor_follows_a_raised_base(tmp_path):
    path = write_scene(tmp_path, '<geom name="b" type="sphere" size="0.1" pos="1 0 0.1"/>')
    model = build_arm_model(ARM, "file", scene_file=path, base_pos=(0, 0, 0.5))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    np.testing.assert_allclose(data.geom_xpos[model.geom("floor").id], (0, 0, -0.5))
    np.testing.assert_allclose(data.geom_xpos[model.geom("scene/b").id], (1, 0, -0.4))


# ---------------------------------------------------------------- every supported geom
def test_every_geom_type_is_copied_at_its_compiled_pose(tmp_path):
    write_obj(tmp_path / "box.obj", *_box_mesh(0.1, 0.2, 0.3))
    path = write_scene(tmp_path, """\
        <geom name="ground" type="plane" size="2 2 0.1" pos="0 0 -0.2"/>
        <body name="stand" pos="2 0 0" euler="0 0 90">
          <geom name="ball" type="sphere" size="0.1" pos="1 0 0"/>
          <geom name="rod" type="capsule" fromto="0 0 0 0 0 1" size="0.05"/>
          <geom name="egg" type="ellipsoid" size="0.1 0.2 0.3" pos="0 1 0"/>
          <geom name="drum" type="cylinder" size="0.2 0.1" pos="0 -1 0" euler="90 0 0"/>
          <geom name="crate" type="box" size="0.1 0.2 0.3" pos="-1 0 0"/>
          <geom name="part" type="mesh" mesh="box" pos="0 0 2"/>
          <geom type="sphere" size="0.05" pos="0 0 3"/>
        </body>""", assets='<mesh name="box" file="box.obj"/>')
    model = build_arm_model(ARM, "file", scene_file=path)
    names = scene_geoms(model)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    turn = rot("z", math.pi / 2)  # euler in degrees (MJCF's default angle unit)
    stand = np.array([2.0, 0, 0])
    up = np.array([0.0, 0, 1])
    expect = {  # name: (MuJoCo type of the collision twin, centre in the world)
        "ground": (mujoco.mjtGeom.mjGEOM_PLANE, (0, 0, -0.2)),
        "ball": (mujoco.mjtGeom.mjGEOM_SPHERE, stand + turn @ (1, 0, 0)),
        "rod": (mujoco.mjtGeom.mjGEOM_CAPSULE, stand + 0.5 * up),
        "egg": (mujoco.mjtGeom.mjGEOM_ELLIPSOID, stand + turn @ (0, 1, 0)),
        "drum": (mujoco.mjtGeom.mjGEOM_CYLINDER, stand + turn @ (0, -1, 0)),
        "crate": (mujoco.mjtGeom.mjGEOM_MESH, stand + turn @ (-1, 0, 0)),  # boxes -> meshes
        "part": (mujoco.mjtGeom.mjGEOM_MESH, stand + 2 * up),
        "geom7": (mujoco.mjtGeom.mjGEOM_SPHERE, stand + 3 * up),  # unnamed: its index
    }
    for name, (kind, centre) in expect.items():
        g = names[f"scene/{name}"]
        assert model.geom_type[g] == kind, name
        assert f"scene/{name}_vis" in names
        np.testing.assert_allclose(data.geom_xpos[g], centre, atol=1e-6, err_msg=name)
    drum = data.geom_xmat[names["scene/drum"]].reshape(3, 3)
    np.testing.assert_allclose(drum[:, 2], turn @ rot("x", math.pi / 2) @ (0, 0, 1), atol=1e-9)
    np.testing.assert_allclose(model.geom_size[names["scene/drum"]][:2], (0.2, 0.1))
    np.testing.assert_allclose(model.geom_size[names["scene/egg"]], (0.1, 0.2, 0.3))
    # the crate's corners (compiled as a convex mesh) span its box, turned by 90°
    g = names["scene/crate"]
    mesh = model.geom_dataid[g]
    corners = model.mesh_vert[model.mesh_vertadr[mesh]:][:model.mesh_vertnum[mesh]]
    world = data.geom_xpos[g] + corners @ data.geom_xmat[g].reshape(3, 3).T
    np.testing.assert_allclose(world.max(0) - world.min(0), (0.4, 0.2, 0.6), atol=1e-6)
    report = load_scene_file(path).meshes
    assert [(r.name, r.convex, r.n_parts) for r in report] == [("box", True, 0)]
    assert not (tmp_path / "box.obj.coacd").exists()


def _box_mesh(hx, hy, hz):
    corners = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
    hull = ConvexHull(corners)
    faces = []
    for simplex, equation in zip(hull.simplices, hull.equations, strict=True):
        a, b, c = corners[simplex]
        faces.append(simplex if np.cross(b - a, c - a) @ equation[:3] > 0 else simplex[::-1])
    return corners, np.array(faces)


# ----------------------------------------------------------------- the U-shaped fixture
def _u_scene(directory: Path, mesh_file="u.obj", pos="0 0 0", name="cell.xml",
             **mesh_attrs) -> Path:
    attrs = " ".join(f'{k}="{v}"' for k, v in mesh_attrs.items())
    return write_scene(directory, f'<body name="fixture" pos="{pos}"><geom name="u" '
                       'type="mesh" mesh="u"/></body>', name=name,
                       assets=f'<mesh name="u" file="{mesh_file}" {attrs}/>')


def _hulls(model, names):
    """Half-space forms (scipy) of every collision mesh geom of the U, in world coordinates."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    hulls = []
    for name, g in names.items():
        if not name.startswith("scene/u") or name.endswith("_vis"):
            continue
        mesh = model.geom_dataid[g]
        local = model.mesh_vert[model.mesh_vertadr[mesh]:][:model.mesh_vertnum[mesh]]
        hulls.append(ConvexHull(data.geom_xpos[g] + local @ data.geom_xmat[g].reshape(3, 3).T))
    return hulls


def _inside_any(hulls, points, tol):
    points = np.atleast_2d(points)
    return np.any([np.all(points @ h.equations[:, :3].T + h.equations[:, 3] <= tol, axis=1)
                   for h in hulls], axis=0)


@pytest.mark.parametrize("fmt", ["obj", "stl"])
def test_u_fixture_gap_is_free_with_parts_and_filled_by_the_hull(tmp_path, fmt, count_coacd):
    vertices, faces = u_channel()
    (write_obj if fmt == "obj" else write_binary_stl)(tmp_path / f"u.{fmt}", vertices, faces)
    path = _u_scene(tmp_path, f"u.{fmt}", pos="1 2 0.5")
    hull_scene = load_scene_file(path, decompose="never")
    parts_scene = load_scene_file(path, coacd_options=FAST)
    assert len(count_coacd) == 1
    (report,) = parts_scene.meshes
    assert report.closed and not report.convex and report.n_parts >= 2
    np.testing.assert_allclose(report.volume, 0.3 * 0.2 * 0.2 - 0.2 * 0.15 * 0.2, rtol=1e-6)
    np.testing.assert_allclose(report.hull_volume, 0.3 * 0.2 * 0.2, rtol=1e-6)
    offset = np.array([1.0, 2.0, 0.5])

    def at(x, y, z):
        return offset + np.array([x, y, z])

    gap = at(0.15, 0.1, 0.15)  # the middle of the gap, 50 mm from each wall
    wall, floor_, above = at(0.025, 0.1, 0.15), at(0.15, 0.1, 0.025), at(0.15, 0.1, 0.3)
    probe = {name: CollisionChecker(probe_model(scene), dof=3)
             for name, scene in (("hull", hull_scene), ("parts", parts_scene))}
    q = np.array([gap, wall, floor_, above])
    assert probe["hull"].collides(q).tolist() == [True, True, True, False]
    assert probe["parts"].collides(q).tolist() == [False, True, True, False]
    # the probe can go down the gap to 5 mm above its floor... with the parts only
    assert not probe["parts"].check_path(above, at(0.15, 0.1, 0.075)).collides
    assert probe["hull"].check_path(above, at(0.15, 0.1, 0.075)).collides

    # The parts cover the U's solid (grid points inside it) and leave the gap's core free.
    # CoACD's cut pieces meet to ~14 µm here (measured: 1.4e-5 m), far inside the
    # checker's clearance (δ/2 = 5 mm per geom): covered within 0.1 mm.
    model = probe_model(parts_scene)
    hulls = _hulls(model, scene_geoms(model))
    assert len(hulls) == report.n_parts
    grid = np.stack(np.meshgrid(np.linspace(0, 0.3, 31), np.linspace(0, 0.2, 11),
                                np.linspace(0, 0.2, 21), indexing="ij"), -1).reshape(-1, 3)
    solid = grid[u_solid_contains(grid)]
    assert np.all(_inside_any(hulls, solid + offset, tol=1e-4))
    core = grid[(grid[:, 0] > 0.07) & (grid[:, 0] < 0.23) & (grid[:, 2] > 0.07)]
    assert not np.any(_inside_any(hulls, core + offset, tol=0.0))


def test_arm_tool_reaches_into_the_u_fixture(tmp_path):
    # Tool pointing down (y3 = −Z0) with its tip 0.1 m deep in a 0.16 m gap.
    width, height, wall, floor_, depth = 0.3, 0.4, 0.07, 0.05, 0.3
    vertices, faces = u_channel(width, height, wall, floor_, depth)
    write_obj(tmp_path / "u.obj", vertices, faces)
    centre = np.array([1.2, 0.0, 1.0])  # wrist centre
    tip_z = centre[2] - 0.35  # the tool is 0.35 m long
    corner = (centre[0] - width / 2, centre[1] - depth / 2, tip_z + 0.1 - height)
    path = _u_scene(tmp_path, pos=_text(corner))
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([(1, 0, 0), (0, 0, -1), (0, 1, 0)])
    pose[:3, 3] = centre
    q, ok = ARM.ik(pose)
    assert ok.any()
    empty = CollisionChecker(build_arm_model(ARM, "empty", tool=True), dof=6)
    hull = CollisionChecker(build_arm_model(ARM, "file", scene_file=path, tool=True,
                                            decompose="never"), dof=6)
    parts = CollisionChecker(build_arm_model(ARM, "file", scene_file=path, tool=True), dof=6)
    free = ok & ~empty.collides(np.nan_to_num(q))
    assert free.any()
    reaching = q[free]
    assert hull.collides(reaching).all()
    assert not parts.collides(reaching).any()
    contacts = {c.geom1 for c in hull.contacts(reaching[0])} | {
        c.geom2 for c in hull.contacts(reaching[0])}
    assert {"tool", "scene/u"} <= contacts
    # and the tool can be lowered into the gap from above along a straight path
    above = pose.copy()
    above[2, 3] += 0.3
    q_above, ok_above = ARM.ik(above)
    k = int(np.flatnonzero(free)[0])
    assert ok_above[k]
    assert not parts.check_path(q_above[k], q[k]).collides


# ------------------------------------------------------------------------------- the cache
def test_cache_is_reused_and_refreshed(tmp_path, count_coacd):
    write_obj(tmp_path / "u.obj", *u_channel())
    path = _u_scene(tmp_path)
    first = load_scene_file(path, coacd_options=FAST).meshes[0]
    assert len(count_coacd) == 1 and not first.cached
    assert first.cache_dir.parent == tmp_path / "u.obj.coacd"
    files = sorted(p.name for p in first.cache_dir.iterdir())
    assert files == ["meta.json"] + [f"part_{k:03d}.obj" for k in range(first.n_parts)]
    contents = {p.name: p.read_bytes() for p in first.cache_dir.glob("part_*.obj")}

    # Second build (through the scene builder): no CoACD run.
    build_arm_model(ARM, "file", scene_file=path, coacd_options=FAST)
    again = load_scene_file(path, coacd_options=FAST).meshes[0]
    assert len(count_coacd) == 1 and again.cached and again.cache_dir == first.cache_dir

    # Other parameters: decomposed again, in their own folder (the first one kept).
    other = load_scene_file(path, coacd_options=FAST | {"threshold": 0.2}).meshes[0]
    assert len(count_coacd) == 2 and other.cache_dir != first.cache_dir
    assert first.cache_dir.exists()

    # A damaged part file: decomposed again, identically (the seed is fixed).
    (first.cache_dir / "part_000.obj").write_text("v 0 0 0\n")
    repaired = load_scene_file(path, coacd_options=FAST).meshes[0]
    assert len(count_coacd) == 3 and not repaired.cached
    assert {p.name: p.read_bytes() for p in first.cache_dir.glob("part_*.obj")} == contents

    # A changed mesh: decomposed again; the decompositions of the old file are removed.
    write_obj(tmp_path / "u.obj", *u_channel(wall=0.06))
    changed = load_scene_file(path, coacd_options=FAST).meshes[0]
    assert len(count_coacd) == 4 and changed.cache_dir != first.cache_dir
    assert sorted(p.name for p in (tmp_path / "u.obj.coacd").iterdir()) == [
        changed.cache_dir.name]


def test_fresh_and_cached_parts_are_identical_and_a_failed_write_is_survived(
    tmp_path, monkeypatch, caplog, count_coacd
):
    write_obj(tmp_path / "u.obj", *u_channel())
    path = _u_scene(tmp_path)
    fresh = load_scene_file(path, coacd_options=FAST).obstacles[0].parts
    cached = load_scene_file(path, coacd_options=FAST).obstacles[0].parts
    assert len(count_coacd) == 1 and len(fresh) == len(cached) >= 2
    for a, b in zip(fresh, cached, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)

    def read_only(*args, **kwargs):
        raise PermissionError("read-only file system")

    monkeypatch.setattr(sf, "_write_cache", read_only)
    write_obj(tmp_path / "v.obj", *u_channel(wall=0.06))
    other = _u_scene(tmp_path, mesh_file="v.obj", name="v.xml")
    with caplog.at_level("WARNING"):
        scene = load_scene_file(other, coacd_options=FAST)
    assert scene.meshes[0].n_parts >= 2 and "cannot cache" in caplog.text
    assert not (tmp_path / "v.obj.coacd").exists()


def test_parallel_builds_share_one_cache(tmp_path):
    import subprocess
    import sys

    write_obj(tmp_path / "u.obj", *u_channel())
    path = _u_scene(tmp_path)
    script = (
        "import hashlib, sys\n"
        "from ikbranch_gym.envs.models.scene_file import load_scene_file\n"
        f"scene = load_scene_file(sys.argv[1], coacd_options={FAST!r})\n"
        "h = hashlib.sha256()\n"
        "for part in scene.obstacles[0].parts:\n"
        "    h.update(part.vertices.tobytes()); h.update(part.faces.tobytes())\n"
        "print(h.hexdigest())\n"
    )
    root = Path(__file__).resolve().parents[3]
    runs = [subprocess.Popen([sys.executable, "-c", script, str(path)], cwd=root,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            for _ in range(3)]
    outputs = [run.communicate(timeout=120) for run in runs]
    assert all(run.returncode == 0 for run in runs), [err for _, err in outputs]
    assert len({out for out, _ in outputs}) == 1
    assert len(list((tmp_path / "u.obj.coacd").iterdir())) == 1  # one folder, no leftovers
    assert load_scene_file(path, coacd_options=FAST).meshes[0].cached


def test_a_mesh_rewritten_within_the_same_second_is_read_anew(tmp_path):
    # MuJoCo's asset cache keys a file by its name and modification time in whole seconds:
    # a rewrite of the same size within that second would be served from the cache.
    import os

    mesh = tmp_path / "u.obj"
    write_obj(mesh, *u_channel(wall=0.05))
    path = _u_scene(tmp_path)
    stamp = (mesh.stat().st_atime, mesh.stat().st_mtime)
    first = load_scene_file(path, decompose="never").meshes[0]
    size = mesh.stat().st_size
    write_obj(mesh, *u_channel(wall=0.06))
    os.utime(mesh, stamp)
    assert mesh.stat().st_size == size
    second = load_scene_file(path, decompose="never").meshes[0]
    assert first.volume == pytest.approx(0.3 * 0.2 * 0.05 + 2 * 0.05 * 0.15 * 0.2, rel=1e-6)
    assert second.volume == pytest.approx(0.3 * 0.2 * 0.05 + 2 * 0.06 * 0.15 * 0.2, rel=1e-6)


def test_scaled_mesh_has_its_own_decomposition(tmp_path, count_coacd):
    write_obj(tmp_path / "u.obj", *u_channel())
    path = _u_scene(tmp_path, scale="2 2 2")
    scene = load_scene_file(path, coacd_options=FAST)
    probe = CollisionChecker(probe_model(scene), dof=3)
    assert probe.collides(np.array([[0.3, 0.2, 0.3], [0.05, 0.2, 0.3]])).tolist() == [False, True]
    plain = write_scene(tmp_path, '<geom name="u" type="mesh" mesh="u"/>', name="plain.xml",
                        assets='<mesh name="u" file="u.obj"/>')
    unscaled = load_scene_file(plain, coacd_options=FAST)
    assert len(count_coacd) == 2
    assert unscaled.meshes[0].cache_dir != scene.meshes[0].cache_dir
    assert unscaled.meshes[0].cache_dir.parent == scene.meshes[0].cache_dir.parent


def test_meshdir_and_decompose_modes(tmp_path, count_coacd):
    (tmp_path / "meshes").mkdir()
    write_obj(tmp_path / "meshes" / "u.obj", *u_channel())
    write_obj(tmp_path / "meshes" / "box.obj", *_box_mesh(0.1, 0.1, 0.1))
    path = write_scene(tmp_path, '<geom name="u" type="mesh" mesh="u"/>'
                       '<geom name="b" type="mesh" mesh="box" pos="1 0 0"/>'
                       '<geom name="deco" type="mesh" mesh="u" pos="2 0 0" contype="0" '
                       'conaffinity="0"/>',
                       head='<compiler meshdir="meshes"/>',
                       assets='<mesh name="u" file="u.obj"/><mesh name="box" file="box.obj"/>')
    auto = load_scene_file(path, coacd_options=FAST)
    assert [(r.name, r.convex) for r in auto.meshes] == [("u", False), ("box", True)]
    assert auto.meshes[0].cache_dir.parent == tmp_path / "meshes" / "u.obj.coacd"
    model = probe_model(auto)
    names = scene_geoms(model)
    assert "scene/deco_vis" in names and not any(n.startswith("scene/deco_part") for n in names)
    assert "scene/b" in names and "scene/u" not in names and "scene/u_part000" in names
    always = load_scene_file(path, decompose="always", coacd_options=FAST)
    assert [r.n_parts >= 1 for r in always.meshes] == [True, True]
    never = load_scene_file(path, decompose="never")
    assert [(r.n_parts, r.convex) for r in never.meshes] == [(0, False), (0, True)]
    assert "scene/u" in scene_geoms(probe_model(never))
    assert len(count_coacd) == 2  # u (cached for "always"), then the box


def test_closed_volume_rule():
    vertices, faces = u_channel()
    closed, volume = sf._closed_volume(sf.MeshPart(vertices, faces))
    assert closed and volume == pytest.approx(0.006, rel=1e-12)
    # a face missing: open; a face flipped: not consistently oriented
    assert not sf._closed_volume(sf.MeshPart(vertices, faces[1:]))[0]
    flipped = faces.copy()
    flipped[0] = flipped[0][::-1]
    assert not sf._closed_volume(sf.MeshPart(vertices, flipped))[0]
    # duplicated vertices (STL-style soup) are merged first
    soup = vertices[faces].reshape(-1, 3)
    closed, volume = sf._closed_volume(sf.MeshPart(soup, np.arange(len(soup)).reshape(-1, 3)))
    assert closed and volume == pytest.approx(0.006, rel=1e-12)


# ------------------------------------------------------------------------------ bad files
BAD_SCENES = [
    # (id, body, assets, options, expected fragment, element)
    ("joint", '<body name="clamp"><joint name="slide1" type="slide"/><geom size="0.1"/></body>',
     "", {}, "has joint 'slide1': obstacles must be static", "body 'clamp'"),
    ("freejoint", '<body name="loose"><freejoint/><geom size="0.1"/></body>', "", {},
     "obstacles must be static", "body 'loose'"),
    ("mocap", '<body name="target" mocap="true"><geom size="0.1"/></body>', "", {},
     "mocap body", "body 'target'"),
    ("hfield", '<geom name="terrain" type="hfield" hfield="h"/>',
     '<hfield name="h" nrow="2" ncol="2" size="1 1 0.1 0.1"/>', {},
     "geom type HFIELD is not supported", "geom 'terrain'"),
    ("flex", '<flexcomp name="cloth" type="grid" count="3 3 1" spacing="0.1 0.1 0.1" dim="2">'
     '<pin id="0 1 2 3 4 5 6 7 8"/></flexcomp>', "", {},
     "flex (deformable) elements are not obstacles", "flex 'cloth'"),
    ("site and options", '<site name="arm_base" pos="1 0 0"/>', "", {"base_pos": (1, 0, 0)},
     "base_pos was given too", "site 'arm_base'"),
    ("site quat", '<site name="arm_base" quat="2 0 0 0"/>', "", {},
     "has norm 2.0, not 1 within 1e-06", "site 'arm_base'"),
    ("base quat", '<geom size="0.1"/>', "", {"base_quat": (1, 0, 0, 0.01)},
     "base_quat [1.0, 0.0, 0.0, 0.01] has norm", ""),
    ("quat and rpy", '<geom size="0.1"/>', "", {"base_quat": (1, 0, 0, 0), "base_rpy": (0, 0, 0)},
     "give base_quat or base_rpy, not both", ""),
    ("base pos shape", '<geom size="0.1"/>', "", {"base_pos": (1, 0)},
     "base_pos must be 3 numbers", ""),
    ("base pos nan", '<geom size="0.1"/>', "", {"base_pos": (1, 0, math.nan)},
     "base_pos contains NaN", ""),
    ("missing mesh file", '<geom type="mesh" mesh="m"/>', '<mesh name="m" file="absent.stl"/>',
     {}, "MuJoCo cannot compile it", ""),
    ("bad attribute", '<geom name="g" size="0.1" colour="red"/>', "", {},
     "MuJoCo cannot compile it", ""),
    ("mesh in millimetres", '<geom name="jig" type="mesh" mesh="jig"/>',
     '<mesh name="jig" vertex="0 0 0  400 0 0  0 300 0  0 0 200"/>', {},
     "m: is it in millimetres? MuJoCo reads meshes in metres", "geom 'jig'"),
]


@pytest.mark.parametrize(
    ("body", "assets", "options", "fragment", "element"),
    [case[1:] for case in BAD_SCENES], ids=[case[0] for case in BAD_SCENES],
)
def test_bad_scene_files(tmp_path, body, assets, options, fragment, element):
    path = write_scene(tmp_path, body, assets=assets)
    with pytest.raises(SceneFileError) as caught:
        build_arm_model(ARM, "file", scene_file=path, **options)
    error = caught.value
    assert isinstance(error, ValueError)
    assert fragment in error.problem, str(error)
    assert error.element == element and error.path == str(path)
    assert str(error).startswith(f"{path}: {element + ': ' if element else ''}")


def test_mujoco_messages_are_passed_on(tmp_path):
    path = write_scene(tmp_path, '<geom type="mesh" mesh="m"/>',
                       assets='<mesh name="m" file="absent.stl"/>')
    with pytest.raises(SceneFileError, match=r"absent\.stl"):
        load_scene_file(path)
    broken = tmp_path / "broken.xml"
    broken.write_text("<mujoco><worldbody><geom size='0.1'></worldbody></mujoco>")
    with pytest.raises(SceneFileError, match=r"broken\.xml: MuJoCo cannot compile it: .*XML"):
        load_scene_file(broken)


def test_missing_file_and_bad_arguments(tmp_path):
    with pytest.raises(SceneFileError, match="no such file"):
        build_arm_model(ARM, "file", scene_file=tmp_path / "absent.xml")
    with pytest.raises(SceneFileError, match="not a file"):
        load_scene_file(tmp_path)
    with pytest.raises(ValueError, match=r"scene='file' needs scene_file=PATH"):
        build_arm_model(ARM, "file")
    path = write_scene(tmp_path, '<geom size="0.1"/>')
    with pytest.raises(ValueError, match="decompose must be one of"):
        load_scene_file(path, decompose="sometimes")
    with pytest.raises(ValueError, match=r"unknown coacd_options \['thresh'\]"):
        load_scene_file(path, coacd_options={"thresh": 0.1})


def test_errors_pickle_whole():
    import pickle

    error = SceneFileError("cell.xml", "has joint 'j'", "body 'b'")
    copy = pickle.loads(pickle.dumps(error))
    assert type(copy) is SceneFileError and str(copy) == str(error)
    assert (copy.path, copy.element, copy.problem) == (error.path, error.element, error.problem)


def test_scene_file_is_registered():
    from ikbranch_gym.envs.models import SCENES

    assert SCENES["file"] is sf.file_scene
