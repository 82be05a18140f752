"""Waypoint files (envs/tasks/waypoint_file.py): formats, exact round trip, bad files.

Expected poses are built here from first principles (textbook quaternion formula, rotation
matrices from elementary rotations, the four points laid out along the frame's axes), never
with the module under test.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.paper_example import (
    POSITION_POINTS_MM,
    TOOL_ABC_MM,
    example_poses,
)
from ikbranch_gym.envs.tasks import TASKS
from ikbranch_gym.envs.tasks.waypoint_file import (
    QUATERNION_TOL,
    ROTATION_TOL,
    WaypointFileError,
    read_waypoints,
    write_waypoints,
)
from tests.envs.tasks.helpers import all_paths_free, everywhere_free

MATRIX_HEADER = "x,y,z,r11,r12,r13,r21,r22,r23,r31,r32,r33"
QUAT_HEADER = "x,y,z,qw,qx,qy,qz"
POINTS_HEADER = "p1x,p1y,p1z,p2x,p2y,p2z,p3x,p3y,p3z,p4x,p4y,p4z"


# ------------------------------------------------------------------ independent references
def textbook_quaternion_matrix(w, x, y, z) -> np.ndarray:
    """R(q) for a unit quaternion q = w + xi + yj + zk (e.g. Shoemake 1985)."""
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def euler_zyx(yaw, pitch, roll) -> np.ndarray:
    cz, sz, cy, sy, cx, sx = (f(a) for a in (yaw, pitch, roll) for f in (math.cos, math.sin))
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    return rz @ ry @ rx


def homogeneous(rotation, position) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = rotation, position
    return pose


def random_poses(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.array([
        homogeneous(euler_zyx(*rng.uniform(-np.pi, np.pi, 3)), rng.normal(scale=2.0, size=3))
        for _ in range(n)
    ])


def unit_quaternions(n: int, seed: int) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def write_table(path, header: list[str], rows: list[list]) -> None:
    """A CSV (header row) or JSON (list of objects) file, numbers as repr."""
    if path.suffix == ".csv":
        lines = [",".join(header)] + [",".join(map(_cell, row)) for row in rows]
        path.write_text("\n".join(lines) + "\n")
    else:
        path.write_text(json.dumps([dict(zip(header, row, strict=True)) for row in rows]))


def _cell(value) -> str:
    return value if isinstance(value, str) else repr(float(value))


# ------------------------------------------------------------------------------ formats
@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_kuka_frames_in_mm_and_degrees(tmp_path, suffix):
    # KUKA's A, B, C: R = Rz(A)·Ry(B)·Rx(C), angles in degrees, x, y, z in mm.
    rng = np.random.default_rng(8)
    angles = rng.uniform(-180, 180, size=(5, 3))
    positions = rng.uniform(-900, 900, size=(5, 3))
    path = tmp_path / f"k{suffix}"
    write_table(path, ["x", "y", "z", "A", "B", "C"],
                [[*p, *a] for p, a in zip(positions, angles, strict=True)])
    file = read_waypoints(path)
    assert file.format == "kuka"
    for pose, p, (a, b, c) in zip(file.poses, positions, angles, strict=True):
        expected = homogeneous(euler_zyx(*np.radians([a, b, c])), p / 1000.0)
        np.testing.assert_allclose(pose, expected, atol=1e-15)
    np.testing.assert_allclose(read_waypoints(path, units="m").poses[:, :3, 3], positions,
                               atol=1e-12)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_abb_robtargets_in_mm_with_their_quaternions(tmp_path, suffix):
    q = unit_quaternions(5, seed=9)
    positions = np.random.default_rng(10).uniform(-900, 900, size=(5, 3))
    path = tmp_path / f"a{suffix}"
    write_table(path, ["x", "y", "z", "q1", "q2", "q3", "q4"],
                [[*p, *quat] for p, quat in zip(positions, q, strict=True)])
    file = read_waypoints(path)
    assert file.format == "abb"
    for pose, p, quat in zip(file.poses, positions, q, strict=True):
        np.testing.assert_allclose(pose, homogeneous(textbook_quaternion_matrix(*quat),
                                                     p / 1000.0), atol=1e-15)
    quaternion_file = tmp_path / f"m{suffix}"  # the metre formats take units too
    write_table(quaternion_file, QUAT_HEADER.split(","), [[*p, *quat] for p, quat in
                                                         zip(positions, q, strict=True)])
    np.testing.assert_allclose(read_waypoints(quaternion_file, units="mm").poses,
                               file.poses, atol=1e-15)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_quaternion_rows_are_the_textbook_rotation(tmp_path, suffix):
    q = unit_quaternions(50, seed=1)
    xyz = np.random.default_rng(2).normal(size=(50, 3))
    path = tmp_path / f"q{suffix}"
    write_table(path, QUAT_HEADER.split(","), [[*p, *qq] for p, qq in zip(xyz, q, strict=True)])
    file = read_waypoints(path)
    assert file.format == "quaternion" and len(file) == 50 and file.poses.dtype == np.float64
    expected = np.array([homogeneous(textbook_quaternion_matrix(*qq), p)
                         for p, qq in zip(xyz, q, strict=True)])
    np.testing.assert_allclose(file.poses, expected, rtol=0, atol=1e-15)
    assert np.array_equal(file.poses[:, :3, 3], xyz)  # positions exactly as written
    assert file.names == tuple(f"wp{i}" for i in range(50))


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_quaternion_examples_by_hand(tmp_path, suffix):
    s = math.sqrt(0.5)
    path = tmp_path / f"q{suffix}"
    # Identity; a half turn about x; a quarter turn about z (x → y); -q is the same rotation.
    write_table(path, ["name", *QUAT_HEADER.split(",")], [
        ["home", 0.5, 0, 1, 1, 0, 0, 0],
        ["flip", 0, 0, 0, 0, 1, 0, 0],
        ["quarter", 1, 2, 3, s, 0, 0, s],
        ["quarter-", 1, 2, 3, -s, 0, 0, -s],
    ])
    file = read_waypoints(path)
    assert file.names == ("home", "flip", "quarter", "quarter-")
    np.testing.assert_array_equal(file.poses[0], homogeneous(np.eye(3), (0.5, 0, 1)))
    np.testing.assert_array_equal(file.poses[1][:3, :3], np.diag([1.0, -1.0, -1.0]))
    quarter = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    np.testing.assert_allclose(file.poses[2][:3, :3], quarter, atol=1e-15)
    np.testing.assert_allclose(file.poses[3], file.poses[2], atol=1e-15)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_matrix_rows_are_read_exactly(tmp_path, suffix):
    poses = random_poses(40, seed=3)
    path = tmp_path / f"m{suffix}"
    write_table(path, MATRIX_HEADER.split(","),
                [[*pose[:3, 3], *pose[:3, :3].ravel()] for pose in poses])
    file = read_waypoints(path)
    assert file.format == "matrix"
    assert np.array_equal(file.poses, poses)  # the text is repr: bit for bit


def test_matrix_columns_are_rows_of_the_rotation(tmp_path):
    # r12 is row 1, column 2: a quarter turn about z has r12 = -1 and r21 = +1.
    path = tmp_path / "m.csv"
    path.write_text(MATRIX_HEADER + "\n1,2,3,0,-1,0,1,0,0,0,0,1\n")
    rotation = read_waypoints(path).poses[0][:3, :3]
    np.testing.assert_array_equal(rotation @ (1, 0, 0), (0, 1, 0))


def _points_mm(pose: np.ndarray, a: float, b: float, c: float) -> list[float]:
    """O and O + a·x3, O + b·y3, O + c·z3 in mm for a pose in metres."""
    origin = pose[:3, 3] * 1000.0
    return [*origin, *(origin + a * pose[:3, 0]), *(origin + b * pose[:3, 1]),
            *(origin + c * pose[:3, 2])]


@pytest.mark.parametrize("suffix", [".csv", ".json"])
@pytest.mark.parametrize("abc_as", ["columns", "options"])
def test_four_points_in_mm(tmp_path, suffix, abc_as):
    poses = random_poses(20, seed=4)
    abc = (40.0, 250.0, 60.0)
    path = tmp_path / f"p{suffix}"
    header = POINTS_HEADER.split(",") + (["a", "b", "c"] if abc_as == "columns" else [])
    rows = [_points_mm(pose, *abc) + (list(abc) if abc_as == "columns" else []) for pose in poses]
    write_table(path, header, rows)
    options = dict(zip("abc", abc, strict=True)) if abc_as == "options" else {}
    file = read_waypoints(path, **options)
    assert file.format == "points"
    np.testing.assert_allclose(file.poses, poses, rtol=0, atol=1e-12)


def test_four_points_with_a_b_c_per_row(tmp_path):
    poses = random_poses(2, seed=5)
    path = tmp_path / "p.csv"
    write_table(path, [*POINTS_HEADER.split(","), "a", "b", "c"],
                [[*_points_mm(poses[0], 10, 20, 30), 10, 20, 30],
                 [*_points_mm(poses[1], 100, 200, 300), 100, 200, 300]])
    np.testing.assert_allclose(read_waypoints(path).poses, poses, atol=1e-12)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_papers_worked_example_as_a_four_point_file(tmp_path, suffix):
    # The paper's points typed as printed (mm), a, b, c as printed.
    path = tmp_path / f"paper{suffix}"
    header = ["name", *POINTS_HEADER.split(",")]
    rows = [[f"position {k}", *(v for point in POSITION_POINTS_MM[k] for v in point)]
            for k in (1, 2)]
    if suffix == ".csv":
        path.write_text(",".join(header) + "\n" + "\n".join(
            ",".join(str(v) for v in row) for row in rows) + "\n")
    else:
        write_table(path, header, rows)
    a, b, c = TOOL_ABC_MM
    file = read_waypoints(path, a=a, b=b, c=c)
    assert file.names == ("position 1", "position 2")
    assert np.array_equal(file.poses, example_poses())
    # and independently: the printed point layout (tool along +X0, then up along +Z0)
    np.testing.assert_allclose(file.poses[0][:3, 3], (0.525, 1.272, 0.8))
    np.testing.assert_allclose(file.poses[0][:3, 1], (1, 0, 0), atol=1e-12)
    np.testing.assert_allclose(file.poses[1][:3, 1], (0, 0, 1), atol=1e-12)


def test_names_extras_lines_and_blank_lines(tmp_path):
    path = tmp_path / "n.csv"
    path.write_text(
        "name,x,y,z,qw,qx,qy,qz,speed\n"
        "\n"
        "a,0,0,0,1,0,0,0,0.5\n"
        ",0,0,1,1,0,0,0,fast\n"
        "\n"
        "\"c, quoted\",0,1,0,1,0,0,0,1\n"
    )
    with pytest.raises(WaypointFileError, match="unknown column 'speed'"):
        read_waypoints(path)
    file = read_waypoints(path, extra_columns=["speed"])
    assert file.names == ("a", "", "c, quoted")
    assert file.lines == (3, 4, 6)  # physical lines, header = 1, blank lines counted
    assert file.extras == {"speed": ("0.5", "fast", "1")}
    error = file.row_error(2, "out of reach")
    assert isinstance(error, ValueError) and error.line == 6
    assert str(error) == f"{path}: line 6: out of reach" and file.where(1) == "line 4"


def test_segments_from_blank_lines_and_the_segment_column(tmp_path):
    """A segment begins after a blank line between rows (CSV) and where the segment
    column's value changes; blank lines before the first row or after the last do not
    count; without either the file is one segment."""
    row = "0,0,0,1,0,0,0"
    path = tmp_path / "s.csv"
    path.write_text(f"{QUAT_HEADER}\n\n{row}\n{row}\n\n\n{row}\n{row}\n\n{row}\n\n")
    np.testing.assert_array_equal(read_waypoints(path).segments, [0, 0, 1, 1, 2])
    path.write_text(f"{QUAT_HEADER}\n{row}\n{row}\n")
    np.testing.assert_array_equal(read_waypoints(path).segments, [0, 0])
    path.write_text(f"{QUAT_HEADER},segment\n{row},pass 1\n{row}, pass 1\n{row},2\n\n"
                    f"{row},2\n{row},pass 3\n")
    np.testing.assert_array_equal(read_waypoints(path).segments, [0, 0, 1, 2, 3])
    entry = {"x": 0, "y": 0, "z": 0, "qw": 1, "qx": 0, "qy": 0, "qz": 0}
    json_path = tmp_path / "s.json"
    json_path.write_text(json.dumps([entry | {"segment": value}
                                     for value in (7, 7, "7", "b", "b")]))
    np.testing.assert_array_equal(read_waypoints(json_path).segments, [0, 0, 1, 2, 2])


def test_json_rows_report_entries(tmp_path):
    path = tmp_path / "n.json"
    path.write_text(json.dumps([{"x": 0, "y": 0, "z": 0, "qw": 1, "qx": 0, "qy": 0, "qz": 0}] * 3))
    file = read_waypoints(path)
    assert file.lines == (0, 1, 2) and file.where(2) == "entry 2"
    assert not file.poses.flags.writeable


# ---------------------------------------------------------------------------- tolerances
def test_quaternion_norm_tolerance(tmp_path):
    path = tmp_path / "q.csv"
    for scale, ok in [(1 + 0.9 * QUATERNION_TOL, True), (1 - 0.9 * QUATERNION_TOL, True),
                      (1 + 1.1 * QUATERNION_TOL, False), (1 - 1.1 * QUATERNION_TOL, False)]:
        q = unit_quaternions(1, seed=6)[0] * scale
        write_table(path, QUAT_HEADER.split(","), [[0, 0, 0, *q]])
        if ok:
            rotation = read_waypoints(path).poses[0][:3, :3]
            # the rotation q represents: orthonormal to rounding, not scaled by ‖q‖²
            np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-15)
            np.testing.assert_allclose(
                rotation, textbook_quaternion_matrix(*(q / scale)), atol=1e-15)
        else:
            with pytest.raises(WaypointFileError, match="not 1 within 1e-06"):
                read_waypoints(path)


def test_rotation_matrix_tolerance(tmp_path):
    path = tmp_path / "m.csv"
    rotation = euler_zyx(0.3, -0.2, 1.0)
    for delta, ok in [(0.9 * ROTATION_TOL / 2, True), (1.1 * ROTATION_TOL / 2, False)]:
        # scaling one row by 1 + d changes RᵀR − I by ~2d
        scaled = rotation.copy()
        scaled[:, 1] *= 1 + delta
        write_table(path, MATRIX_HEADER.split(","), [[0, 0, 0, *scaled.ravel()]])
        if ok:
            assert np.array_equal(read_waypoints(path).poses[0][:3, :3], scaled)  # as given
        else:
            with pytest.raises(WaypointFileError, match="not orthonormal"):
                read_waypoints(path)


# --------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("suffix", [".csv", ".json"])
@pytest.mark.parametrize("with_names", [False, True])
def test_exact_round_trip(tmp_path, suffix, with_names):
    rng = np.random.default_rng(7)
    poses = random_poses(200, seed=8)
    poses[:5, :3, 3] *= rng.choice([1e-300, 1e-9, 1e6, 1e300], size=(5, 1))  # extreme values
    poses[5, :3, 3] = (-0.0, 0.0, 5e-324)
    names = [f"p{i}" if i % 3 else f"name, with \"quotes\" {i}" for i in range(200)]
    path = write_waypoints(tmp_path / f"r{suffix}", poses, names if with_names else None)
    file = read_waypoints(path)
    assert np.array_equal(file.poses, poses)
    assert np.array_equal(np.signbit(file.poses), np.signbit(poses))
    assert file.names == (tuple(names) if with_names else tuple(f"wp{i}" for i in range(200)))
    assert file.format == "matrix"


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_quaternion_round_trip_to_rounding(tmp_path, suffix):
    poses = random_poses(200, seed=9)
    poses[0, :3, :3] = np.diag([1.0, -1.0, -1.0])  # half turns: trace −1
    poses[1, :3, :3] = np.diag([-1.0, -1.0, 1.0])
    path = write_waypoints(tmp_path / f"q{suffix}", poses, format="quaternion")
    file = read_waypoints(path)
    assert file.format == "quaternion"
    np.testing.assert_allclose(file.poses, poses, rtol=0, atol=2e-15)
    rows = json.loads(path.read_text()) if suffix == ".json" else None
    if rows:
        assert all(row["qw"] >= 0 for row in rows)


def test_a_generated_task_written_and_read_back_is_the_same(tmp_path):
    arm = make_arm("anthropomorphic")
    task = TASKS["helix"](arm, np.random.default_rng(11), 12, everywhere_free,
                          all_paths_free)
    for suffix in (".csv", ".json"):
        file = read_waypoints(write_waypoints(tmp_path / f"task{suffix}", task.poses))
        assert np.array_equal(file.poses, task.poses)
        q_file, ok_file = arm.ik(file.poses)
        q_task, ok_task = arm.ik(task.poses)
        assert np.array_equal(ok_file, ok_task)
        assert np.array_equal(q_file, q_task, equal_nan=True)


@pytest.mark.parametrize(
    ("poses", "kwargs", "fragment"),
    [
        (np.full((1, 4, 4), np.nan), {}, "NaN or inf"),
        (np.eye(4)[None] * 2, {}, "bottom row"),
        (np.diag([1.0, 1.0, 1.1, 1.0])[None], {}, "not a rotation"),
        (np.diag([1.0, 1.0, -1.0, 1.0])[None], {}, "not a rotation"),
        (np.eye(4)[None], {"names": ["a", "b"]}, "2 names for 1 poses"),
        (np.eye(4)[None], {"format": "points"}, "format must be"),
        (np.zeros((0, 4, 4)), {}, "N ≥ 1"),
    ],
)
def test_write_rejects_bad_poses_and_leaves_the_old_file(tmp_path, poses, kwargs, fragment):
    path = tmp_path / "w.csv"
    path.write_text("old")
    with pytest.raises(ValueError, match=fragment):
        write_waypoints(path, poses, **kwargs)
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["w.csv"]  # no temporary left behind


def test_a_written_file_appears_whole_with_an_ordinary_files_mode(tmp_path, monkeypatch):
    # Written through envs.files: the permissions of an ordinary new file (not a
    # temporary file's 0600), and a failure while writing leaves the old file.
    import os
    import stat

    ordinary = tmp_path / "ordinary.csv"
    ordinary.write_text("")
    path = write_waypoints(tmp_path / "w.csv", np.eye(4)[None])
    assert stat.S_IMODE(path.stat().st_mode) == stat.S_IMODE(ordinary.stat().st_mode)
    before = path.read_bytes()

    def full_disk(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full_disk)
    with pytest.raises(OSError, match="No space"):
        write_waypoints(path, random_poses(3, seed=1))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ordinary.csv", "w.csv"]


def test_write_rejects_unknown_suffix(tmp_path):
    with pytest.raises(ValueError, match=r"use \.csv or \.json"):
        write_waypoints(tmp_path / "w.txt", np.eye(4)[None])


# ----------------------------------------------------------------------------- bad files
_Q = "0,0,0,1,0,0,0"  # a good quaternion row's values
_M = "0,0,0,1,0,0,0,1,0,0,0,1"
_P = "525,1272,800,525,1272,750,875,1272,800,525,1222,800"  # the paper's position 1
_PJ = dict(zip(POINTS_HEADER.split(","), map(float, _P.split(",")), strict=True))
_QJ = {"x": 0, "y": 0, "z": 0, "qw": 1, "qx": 0, "qy": 0, "qz": 0}

BAD_FILES = [
    # (id, file name, content, read options, expected fragment, line or entry)
    ("empty csv", "e.csv", "", {}, "empty file", None),
    ("blank csv", "e.csv", "\n  \n", {}, "empty file", None),
    ("empty json", "e.json", "", {}, "empty file", None),
    ("header only", "h.csv", QUAT_HEADER + "\n", {}, "no rows", 1),
    ("json empty list", "h.json", "[]", {}, "no rows", None),
    ("unparseable", "u.csv", f"{QUAT_HEADER}\n{_Q}\n0,0,abc,1,0,0,0\n", {},
     "column z: cannot parse 'abc' as a number", 3),
    ("decimal comma", "u.csv", f"{QUAT_HEADER}\n0,0,\"0,5\",1,0,0,0\n", {},
     "cannot parse '0,5'", 2),
    ("hex number", "u.csv", f"{QUAT_HEADER}\n0x1,0,0,1,0,0,0\n", {}, "cannot parse '0x1'", 2),
    ("empty value", "u.csv", f"{QUAT_HEADER}\n{_Q}\n{_Q}\n0,,0,1,0,0,0\n", {},
     "column y: empty value", 4),
    ("nan", "n.csv", f"{QUAT_HEADER}\nnan,0,0,1,0,0,0\n", {}, "column x: nan is not finite", 2),
    ("inf", "n.csv", f"{MATRIX_HEADER}\n{_M}\n0,0,-inf,1,0,0,0,1,0,0,0,1\n", {},
     "column z: -inf is not finite", 3),
    ("json nan", "n.json", '[{"x":0,"y":0,"z":0,"qw":1,"qx":0,"qy":0,"qz":0},'
     '{"x":NaN,"y":0,"z":0,"qw":1,"qx":0,"qy":0,"qz":0}]', {}, "column x: nan is not finite", 1),
    ("json string number", "s.json", json.dumps([_QJ | {"y": "1.0"}]), {},
     "column y: expected a number, got the string '1.0'", 0),
    ("json bool", "s.json", json.dumps([_QJ, _QJ | {"qw": True}]), {},
     "column qw: expected a number, got true", 1),
    ("json null", "s.json", json.dumps([_QJ | {"qz": None}]), {}, "expected a number, got null",
     0),
    ("missing column", "m.csv", "x,y,z,qw,qx,qy\n0,0,0,1,0,0\n", {},
     "quaternion format: missing column qz", 1),
    ("missing columns", "m.csv", "x,y,r11,r12,r13,r21,r22,r23,r31,r32\n"
     "0,0,1,0,0,0,1,0,0,0\n", {}, "matrix format: missing columns z, r33", 1),
    ("json missing column", "m.json", json.dumps([{k: v for k, v in _QJ.items() if k != "x"}]),
     {}, "missing column x", 0),
    ("quaternion not unit", "q.csv", f"{QUAT_HEADER}\n{_Q}\n0,0,0,1.01,0,0,0\n", {},
     "quaternion norm 1.01 is not 1 within 1e-06", 3),
    ("quaternion zero", "q.json", json.dumps([_QJ | {"qw": 0}]), {}, "quaternion norm 0.0", 0),
    ("not orthonormal", "r.csv", f"{MATRIX_HEADER}\n0,0,0,1,0.01,0,0,1,0,0,0,1\n", {},
     "rotation matrix is not orthonormal", 2),
    ("reflection", "r.csv", f"{MATRIX_HEADER}\n{_M}\n0,0,0,1,0,0,0,1,0,0,0,-1\n", {},
     "a reflection, not a rotation", 3),
    ("points inconsistent", "p.csv", f"{POINTS_HEADER}\n{_P}\n"
     "525,1272,800,525,1272,750,875,1272,800,525,1222,801\n", {"a": 50, "b": 350, "c": 50},
     "four points inconsistent with a, b, c = 50.0, 350.0, 50.0 mm", 3),
    ("points wrong b", "p.csv", f"{POINTS_HEADER}\n{_P}\n", {"a": 50, "b": 300, "c": 50},
     "orthonormal triad", 2),
    ("points left-handed", "p.csv", f"{POINTS_HEADER}\n"
     "525,1272,800,525,1272,750,875,1272,800,525,1322,800\n", {"a": 50, "b": 350, "c": 50},
     "left-handed", 2),
    ("points json", "p.json", json.dumps([_PJ, _PJ | {"p4z": 810.0}]),
     {"a": 50, "b": 350, "c": 50}, "four points inconsistent", 1),
    ("points no abc", "p.csv", f"{POINTS_HEADER}\n{_P}\n", {"a": 50, "c": 50},
     "b (mm) is neither a column nor an option", 1),
    ("abc twice", "p.csv", f"{POINTS_HEADER},a\n{_P},50\n", {"a": 50, "b": 350, "c": 50},
     "a is given both as a column and as an option", 1),
    ("abc column not positive", "p.csv", f"{POINTS_HEADER},a,b,c\n{_P},50,350,50\n{_P},50,0,50\n",
     {}, "column b: 0.0 mm must be positive", 3),
    ("abc option not positive", "p.csv", f"{POINTS_HEADER}\n{_P}\n", {"a": 50, "b": -1, "c": 50},
     "option b = -1 mm: must be positive", None),
    ("quaternion and matrix", "a.csv", f"{QUAT_HEADER},r11\n{_Q},1\n", {},
     "both quaternion (qw…qz) and matrix (r11…r33) columns", 1),
    ("points and position", "a.csv", f"{POINTS_HEADER},x\n{_P},1\n", {"a": 50, "b": 350, "c": 50},
     "both four-point", 1),
    ("unknown column", "k.csv", f"{QUAT_HEADER},speed\n{_Q},1\n", {}, "unknown column 'speed'", 1),
    ("unknown columns json", "k.json", json.dumps([_QJ | {"X": 1, "tool": 2}]), {},
     "unknown columns 'X', 'tool'", 0),
    ("abc in quaternion file", "k.csv", f"{QUAT_HEADER},a\n{_Q},1\n", {},
     "(a, b, c belong to the four-point format)", 1),
    ("abc option for matrix", "k.csv", f"{MATRIX_HEADER}\n{_M}\n", {"a": 50},
     "option a only apply to four-point files", 1),
    ("unrecognised", "k.csv", "X,Y,Z\n1,2,3\n", {}, "cannot recognise the format", 1),
    ("upper case", "k.csv", "X,Y,Z,QW,QX,QY,QZ\n" + _Q + "\n", {}, "cannot recognise", 1),
    ("field count", "f.csv", f"{QUAT_HEADER}\n{_Q}\n{_Q}\n{_Q},7\n", {},
     "expected 7 fields (as in the header), got 8", 4),
    ("duplicate column", "d.csv", "x,y,z,qw,qx,qy,qz,x\n" + _Q + ",0\n", {},
     "column 'x' appears twice", 1),
    ("empty column name", "d.csv", "x,y,z,,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n", {},
     "empty column name", 1),
    ("semicolons", "d.csv", "x;y;z;qw;qx;qy;qz\n0;0;0;1;0;0;0\n", {},
     "the delimiter must be ','", 1),
    ("unterminated quote", "d.csv", f"name,{QUAT_HEADER}\n\"a,{_Q}\n", {}, "malformed CSV", 2),
    ("name not a string", "n.json", json.dumps([_QJ | {"name": 3}]), {},
     "column name: expected a string, got int", 0),
    ("json object", "o.json", json.dumps({"waypoints": [_QJ]}), {},
     "expected a JSON list of objects, got dict", None),
    ("json entry not object", "o.json", json.dumps([_QJ, [1, 2]]), {},
     "expected an object, got list", 1),
    ("json keys differ", "o.json", json.dumps([_QJ, _QJ, _QJ | {"name": "x"}]), {},
     "keys differ from entry 0 (unexpected name)", 2),
    ("invalid json", "o.json", '[\n{"x": 0,\n "y": }\n]', {}, "invalid JSON", 3),
    ("json huge int", "o.json", json.dumps([_QJ | {"x": 10**400}]), {}, "is too large", 0),
    ("segment comes back", "s.csv", f"{QUAT_HEADER},segment\n{_Q},A\n{_Q},B\n{_Q},A\n", {},
     "segment 'A' appears again after another segment (it began at line 2)", 4),
    ("segment comes back json", "s.json", json.dumps([_QJ | {"segment": 1}, _QJ | {"segment": 2},
                                                     _QJ | {"segment": 1}]), {},
     "segment 1 appears again after another segment (it began at entry 0)", 2),
    ("segment empty", "s.csv", f"{QUAT_HEADER},segment\n{_Q},A\n{_Q}, \n", {},
     "column segment: expected a segment name (text or a number), got an empty value", 3),
    ("segment null", "s.json", json.dumps([_QJ | {"segment": None}]), {},
     "column segment: expected a segment name (text or a number), got null", 0),
    ("segment list", "s.json", json.dumps([_QJ | {"segment": [1]}]), {},
     "got [1]", 0),
    ("kuka and quaternion", "k.csv", f"{QUAT_HEADER},A,B,C\n{_Q},0,0,0\n", {},
     "both quaternion (qw…qz) and KUKA (A, B, C) columns: keep one", 1),
    ("abb and matrix", "k.csv", f"{MATRIX_HEADER},q1,q2,q3,q4\n{_M},1,0,0,0\n", {},
     "both matrix (r11…r33) and ABB (q1…q4) columns: keep one", 1),
    ("kuka missing C", "k.csv", "x,y,z,A,B\n0,0,0,0,0\n", {}, "kuka format: missing column C",
     1),
    ("abb not unit", "a.csv", "x,y,z,q1,q2,q3,q4\n0,0,0,1,0,0,0\n0,0,0,1,0.1,0,0\n", {},
     "quaternion norm", 3),
    ("units for points", "p.csv", f"{POINTS_HEADER}\n{_P}\n",
     {"a": 50, "b": 350, "c": 50, "units": "m"}, "the four-point format is always in mm", 1),
    ("units unknown", "u.csv", f"{QUAT_HEADER}\n{_Q}\n", {"units": "cm"},
     "units must be 'm' or 'mm'", None),
    ("suffix", "w.txt", _Q, {}, "unknown file type '.txt'", None),
    ("not utf-8", "b.csv", b"x,y,z\n\xff\xfe\x00", {}, "not UTF-8", None),
]


@pytest.mark.parametrize(
    ("name", "content", "options", "fragment", "place"),
    [case[1:] for case in BAD_FILES],
    ids=[case[0] for case in BAD_FILES],
)
def test_bad_files(tmp_path, name, content, options, fragment, place):
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    with pytest.raises(WaypointFileError) as caught:
        read_waypoints(path, **options)
    error = caught.value
    assert isinstance(error, ValueError)
    assert fragment in error.problem, error.problem
    assert error.path == str(path)
    found = error.line if name.endswith(".csv") or error.entry is None else error.entry
    assert found == place, str(error)
    prefix = f"{path}: " + (
        "" if place is None else f"{'line' if error.line is not None else 'entry'} {place}: "
    )
    assert str(error).startswith(prefix), str(error)


def test_errors_pickle_whole():
    import pickle

    for error in (WaypointFileError("f.csv", "bad", line=3),
                  WaypointFileError("f.json", "bad", entry=2), WaypointFileError("f", "x")):
        copy = pickle.loads(pickle.dumps(error))
        assert type(copy) is WaypointFileError and str(copy) == str(error)
        assert (copy.path, copy.line, copy.entry, copy.problem) == (
            error.path, error.line, error.entry, error.problem)


def test_missing_file(tmp_path):
    with pytest.raises(WaypointFileError, match="no such file") as caught:
        read_waypoints(tmp_path / "absent.csv")
    assert caught.value.line is None and str(tmp_path / "absent.csv") in str(caught.value)


def test_json_invalid_reports_the_line_not_an_entry(tmp_path):
    path = tmp_path / "o.json"
    path.write_text('[\n{"x": 0,\n "y": }\n]')
    with pytest.raises(WaypointFileError) as caught:
        read_waypoints(path)
    assert caught.value.line == 3 and caught.value.entry is None
