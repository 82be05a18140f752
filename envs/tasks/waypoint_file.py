"""Waypoint files: poses of a real job read from CSV or JSON, and written back.

Pure numpy and the standard library (``csv``, ``json``); no simulator. The full
description, with every error and its tolerance, is ``docs/files.md``.

A file is a table: CSV with a header row, or JSON as a list of objects that all have the
same keys. The format is recognised from the column names (whitespace around a CSV header
cell is ignored, names are case-sensitive):

``quaternion``  ``x,y,z,qw,qx,qy,qz``: position (m) and a unit quaternion, w first.
``matrix``      ``x,y,z,r11,r12,r13,r21,r22,r23,r31,r32,r33``: position (m) and the
                rotation matrix by rows (r12 is row 1, column 2).
``kuka``        ``x,y,z,A,B,C``: a KUKA frame, position in mm and the angles A, B, C
                (degrees) of R = Rz(A)·Ry(B)·Rx(C), as the controller shows them.
``abb``         ``x,y,z,q1,q2,q3,q4``: an ABB ``robtarget``'s position (mm) and unit
                quaternion ``orient`` (q1 the scalar part).
``points``      ``p1x,p1y,p1z,…,p4x,p4y,p4z``: the paper's four points (eq. 3) in mm,
                O and the points (a, 0, 0), (0, b, 0), (0, 0, c) of the gripper frame, with
                ``a,b,c`` (mm) as columns or as the ``a=``/``b=``/``c=`` options (each one
                way, not both).

An optional ``name`` column labels the rows. Process segments (``envs/process.py``): a
new segment begins where the optional ``segment`` column's value changes (a segment's
rows must be consecutive; any text or number names it) and, in CSV, after a blank line
between rows; without either the whole file is one segment. Any other column is an error unless the
caller lists it in ``extra_columns`` (its raw values, CSV text or JSON values, are then
returned in ``WaypointFile.extras``): a misspelt column must not be dropped silently.

Every problem raises :class:`WaypointFileError` (a ``ValueError``) with the file, the place
(CSV: the physical line, the header being line 1; JSON: the 0-based list index, "entry 3")
and the problem. Nothing is clamped or normalised beyond the stated tolerances.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.files import write_atomically
from ikbranch_gym.envs.kinematics import pose_from_points
from ikbranch_gym.envs.kinematics.rotations import (
    ORTHONORMAL_TOL,
    quaternion_matrix,
    rot_x,
    rot_y,
    rot_z,
    rotation_to_quaternion,
)

#: Largest accepted |‖q‖ − 1| of a quaternion. Within it, the row's rotation is the one q
#: represents (the rotation of q/‖q‖: the rounding of a printed unit quaternion, 6+
#: significant digits, is absorbed); beyond it the row is an error, never normalised.
QUATERNION_TOL = 1e-6
#: Largest accepted entry of |RᵀR − I| of a rotation matrix (the kinematics' own
#: ``ORTHONORMAL_TOL``, so a pose this reader accepts is one ``arm.ik`` accepts); det R
#: must be positive (a reflection is an error). The matrix is used as given.
ROTATION_TOL = ORTHONORMAL_TOL

POSITION = ("x", "y", "z")
QUATERNION = ("qw", "qx", "qy", "qz")
MATRIX = tuple(f"r{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))
POINTS = tuple(f"p{k}{axis}" for k in (1, 2, 3, 4) for axis in "xyz")
ABC = ("a", "b", "c")
NAME = "name"
SEGMENT = "segment"

#: The columns of each format (besides ``name``; ``a,b,c`` may join ``points``).
KUKA_ANGLES = ("A", "B", "C")
ABB_ORIENT = ("q1", "q2", "q3", "q4")
FORMATS: dict[str, tuple[str, ...]] = {
    "quaternion": POSITION + QUATERNION,
    "matrix": POSITION + MATRIX,
    "kuka": POSITION + KUKA_ANGLES,
    "abb": POSITION + ABB_ORIENT,
    "points": POINTS,
}
#: The unit of x, y, z each format gives by default (``units`` overrides it; the four
#: points are always in mm).
DEFAULT_UNITS = {"quaternion": "m", "matrix": "m", "kuka": "mm", "abb": "mm", "points": "mm"}
UNITS = {"m": 1.0, "mm": 0.001}
#: The formats a pose's orientation comes from (columns after x, y, z).
ROTATIONS = ("quaternion", "matrix", "kuka", "abb")

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_NOT_FINITE = {"nan", "+nan", "-nan", "inf", "+inf", "-inf", "infinity", "+infinity",
               "-infinity"}


class WaypointFileError(ValueError):
    """A bad waypoint file: ``path``, ``line`` (CSV, 1-based, header = 1) or ``entry``
    (JSON, 0-based list index) where known, and the ``problem``."""

    def __init__(
        self, path: str | os.PathLike, problem: str, line: int | None = None,
        entry: int | None = None,
    ) -> None:
        self.path = str(path)
        self.line = line
        self.entry = entry
        self.problem = problem
        super().__init__(f"{self.path}: {self.where + ': ' if self.where else ''}{problem}")

    def __reduce__(  # pickles whole (e.g. raised in a vector env's worker)
        self,
    ) -> tuple[type[WaypointFileError], tuple[str, str, int | None, int | None]]:
        return type(self), (self.path, self.problem, self.line, self.entry)

    @property
    def where(self) -> str:
        if self.line is not None:
            return f"line {self.line}"
        if self.entry is not None:
            return f"entry {self.entry}"
        return ""


@dataclass(frozen=True, eq=False)
class WaypointFile:
    """What :func:`read_waypoints` returns.

    ``poses`` (N, 4, 4) float64, metres, read-only, bottom row (0, 0, 0, 1). ``names`` one
    per row: the ``name`` column's text ("" where blank) or ``wp0``, ``wp1``, … without
    one. ``lines``: where each row came from (CSV physical line; JSON list index), for
    reporting per-row problems found later (e.g. a pose no branch reaches) with
    :meth:`row_error`. ``extras``: the raw values (CSV text, JSON values) of the allowed
    ``extra_columns`` present in the file. ``segments`` (N,) int64: each row's process
    segment, 0, 1, … in file order (all 0 without a ``segment`` column or blank lines).
    """

    poses: np.ndarray
    names: tuple[str, ...]
    path: Path
    format: str
    lines: tuple[int, ...] = ()
    extras: dict[str, tuple] = field(default_factory=dict)
    segments: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        if len(self.segments) != len(self.poses):  # made without segments: one segment
            object.__setattr__(self, "segments", np.zeros(len(self.poses), dtype=np.int64))

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def kind(self) -> str:
        """``"csv"`` or ``"json"``."""
        return _kind(self.path)

    def where(self, row: int) -> str:
        """``"line L"`` (CSV) or ``"entry E"`` (JSON) of pose ``row``."""
        return self.row_error(row, "").where

    def row_error(self, row: int, problem: str) -> WaypointFileError:
        """A :class:`WaypointFileError` for pose ``row`` (e.g. unreachable), to raise or
        print."""
        place = self.lines[row]
        if self.kind == "csv":
            return WaypointFileError(self.path, problem, line=place)
        return WaypointFileError(self.path, problem, entry=place)


# ------------------------------------------------------------------------------- reading
def read_waypoints(
    path: str | os.PathLike,
    *,
    a: float | None = None,
    b: float | None = None,
    c: float | None = None,
    extra_columns: Iterable[str] = (),
    units: str | None = None,
) -> WaypointFile:
    """Read a waypoint file (``.csv`` or ``.json``, by suffix).

    ``a``, ``b``, ``c`` (mm): the four-point format's distances when the file has no such
    columns. ``extra_columns``: names of further columns to accept (returned raw in
    ``extras``). ``units`` (``"m"`` or ``"mm"``): of x, y, z, overriding the format's
    default (``DEFAULT_UNITS``; not for the four-point format). Raises
    :class:`WaypointFileError` naming the file, line/entry and problem.
    """
    path = Path(path)
    kind = _kind(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise WaypointFileError(path, "no such file") from None
    except UnicodeDecodeError as exc:
        raise WaypointFileError(path, f"not UTF-8 text ({exc.reason})") from None
    except OSError as exc:
        raise WaypointFileError(path, f"cannot read: {exc.strerror}") from None
    if not text.strip():
        raise WaypointFileError(path, "empty file")
    if units is not None and units not in UNITS:
        raise WaypointFileError(path, f"units must be 'm' or 'mm', got {units!r}")
    rows = _csv_rows(path, text) if kind == "csv" else _json_rows(path, text)
    return _parse(path, kind, *rows, {"a": a, "b": b, "c": c}, tuple(extra_columns), units)


def _kind(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".json"):
        raise WaypointFileError(path, f"unknown file type {suffix!r}: use .csv or .json")
    return suffix[1:]


def _csv_rows(path: Path, text: str) -> tuple[list[str], list[tuple[int, dict]], set[int]]:
    """Header, (line, {column: text}) per data row, and the rows that follow a blank line
    after an earlier row (they begin a process segment); blank lines are skipped."""
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    try:
        header: list[str] | None = None
        rows: list[tuple[int, dict]] = []
        breaks: set[int] = set()
        for record in reader:
            if not record or all(not cell.strip() for cell in record):
                if rows:
                    breaks.add(len(rows))
                continue
            if header is None:
                header = [cell.strip() for cell in record]
                _check_header(path, header, reader.line_num)
                continue
            if len(record) != len(header):
                raise WaypointFileError(
                    path, f"expected {len(header)} fields (as in the header), got {len(record)}",
                    line=reader.line_num,
                )
            rows.append((reader.line_num, dict(zip(header, record, strict=True))))
    except csv.Error as exc:
        raise WaypointFileError(path, f"malformed CSV: {exc}", line=reader.line_num) from None
    assert header is not None  # the text is not blank
    return header, rows, {row for row in breaks if row < len(rows)}


def _check_header(path: Path, header: list[str], line: int) -> None:
    for cell in header:
        if not cell:
            raise WaypointFileError(path, "empty column name in the header", line=line)
        if header.count(cell) > 1:
            raise WaypointFileError(path, f"column {cell!r} appears twice", line=line)
    if len(header) == 1 and any(sep in header[0] for sep in ";\t"):
        raise WaypointFileError(
            path, f"one column {header[0]!r}: the delimiter must be ',' (comma)", line=line
        )


def _json_rows(path: Path, text: str) -> tuple[list[str], list[tuple[int, dict]], set[int]]:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise WaypointFileError(
            path, f"invalid JSON: {exc.msg} (column {exc.colno})", line=exc.lineno
        ) from None
    if not isinstance(data, list):
        raise WaypointFileError(
            path, f"expected a JSON list of objects, got {type(data).__name__}"
        )
    if not data:
        raise WaypointFileError(path, "no rows")
    header: list[str] | None = None
    rows = []
    for index, entry in enumerate(data):
        if not isinstance(entry, dict):
            raise WaypointFileError(
                path, f"expected an object, got {type(entry).__name__}", entry=index
            )
        if header is None:
            header = list(entry)
        elif set(entry) != set(header):
            missing = sorted(set(header) - set(entry))
            unexpected = sorted(set(entry) - set(header))
            detail = "; ".join(
                part for part in (
                    f"missing {', '.join(missing)}" if missing else "",
                    f"unexpected {', '.join(unexpected)}" if unexpected else "",
                ) if part
            )
            raise WaypointFileError(
                path, f"keys differ from entry 0 ({detail}): every entry needs the same keys",
                entry=index,
            )
        rows.append((index, entry))
    assert header is not None
    return header, rows, set()


def _parse(
    path: Path,
    kind: str,
    header: list[str],
    rows: list[tuple[int, dict]],
    breaks: set[int],
    options: dict[str, float | None],
    extra_columns: tuple[str, ...],
    units: str | None = None,
) -> WaypointFile:
    header_place = {"line": 1} if kind == "csv" else {"entry": 0}
    fmt = _recognise(path, header, header_place, options, extra_columns)
    if units is not None and fmt == "points":
        raise WaypointFileError(path, "units apply to x, y, z; the four-point format is "
                                "always in mm", **header_place)
    scale = UNITS[units or DEFAULT_UNITS[fmt]]
    if not rows:
        raise WaypointFileError(path, "no rows (only a header)", **header_place)

    def place(where: int) -> dict:
        return {"line": where} if kind == "csv" else {"entry": where}

    columns = FORMATS[fmt] + tuple(key for key in ABC if fmt == "points" and key in header)
    values = np.empty((len(rows), len(columns)))
    for r, (where, row) in enumerate(rows):
        for k, column in enumerate(columns):
            values[r, k] = _number(path, row[column], column, place(where))
    lines = tuple(where for where, _ in rows)
    table = dict(zip(columns, values.T, strict=True))

    if fmt == "points":
        poses = _points_poses(path, table, options, lines, place)
    else:
        if fmt == "quaternion":
            rotation = _quaternion_rotations(path, table, lines, place)
        elif fmt == "abb":
            rotation = _quaternion_rotations(path, table, lines, place, ABB_ORIENT)
        elif fmt == "kuka":
            rotation = _kuka_rotations(table)
        else:
            rotation = _matrix_rotations(path, table, lines, place)
        poses = np.zeros((len(rows), 4, 4))
        poses[:, :3, :3] = rotation
        poses[:, :3, 3] = np.stack([table[axis] for axis in POSITION], axis=-1) * scale
        poses[:, 3, 3] = 1.0
    poses.flags.writeable = False

    if NAME in header:
        names = tuple(_text(path, row[NAME], NAME, place(where)) for where, row in rows)
    else:
        names = tuple(f"wp{i}" for i in range(len(rows)))
    extras = {
        column: tuple(row[column] for _, row in rows)
        for column in extra_columns if column in header
    }
    segments = _segments(path, header, rows, breaks, place)
    return WaypointFile(poses, names, path, fmt, lines, extras, segments)


def _segments(path: Path, header: list[str], rows: list[tuple[int, dict]], breaks: set[int],
              place: Callable[[int], dict]) -> np.ndarray:
    """(N,) int64: each row's process segment (the module docstring's rules)."""
    begins = np.zeros(len(rows), dtype=bool)
    begins[sorted(breaks)] = True
    if SEGMENT in header:
        seen: dict[tuple[str, object], int] = {}
        previous: object = None
        for r, (where, row) in enumerate(rows):
            value = row[SEGMENT]
            if isinstance(value, str):
                value = value.strip()
            if value == "" or value is None or isinstance(value, bool | list | dict):
                raise WaypointFileError(
                    path, f"column {SEGMENT}: expected a segment name (text or a number), got "
                    f"{json.dumps(value) if not isinstance(value, str) else 'an empty value'}",
                    **place(where))
            key = ("text", value) if isinstance(value, str) else ("number", value)
            if r and key != previous:
                if key in seen:
                    first = place(seen[key])
                    began = (f"line {first['line']}" if "line" in first
                             else f"entry {first['entry']}")
                    raise WaypointFileError(
                        path, f"column {SEGMENT}: segment {value!r} appears again after "
                        f"another segment (it began at {began}); a segment's rows must be "
                        "consecutive", **place(where))
                begins[r] = True
            seen.setdefault(key, where)
            previous = key
    begins[0] = False
    return np.cumsum(begins).astype(np.int64)


def _recognise(
    path: Path,
    header: list[str],
    header_place: dict,
    options: dict[str, float | None],
    extra_columns: tuple[str, ...],
) -> str:
    columns = set(header)
    fmt = _format_of_columns(path, header, columns, header_place)
    _check_columns(path, header, columns, fmt, extra_columns, header_place)
    _check_abc_sources(path, columns, fmt, options, header_place)
    return fmt


def _format_of_columns(path: Path, header: list[str], columns: set[str],
                       header_place: dict) -> str:
    """The format the columns name: one rotation kind, or four points, never a mix."""
    present = {fmt: columns & set(cols) for fmt, cols in FORMATS.items()}
    rotations = [fmt for fmt in ROTATIONS if columns & set(FORMATS[fmt][3:])]
    if len(rotations) >= 2:
        names = {"quaternion": "quaternion (qw…qz)", "matrix": "matrix (r11…r33)",
                 "kuka": "KUKA (A, B, C)", "abb": "ABB (q1…q4)"}
        raise WaypointFileError(
            path, f"both {names[rotations[0]]} and {names[rotations[1]]} columns: keep one",
            **header_place,
        )
    if present["points"] and (rotations or columns & set(POSITION)):
        raise WaypointFileError(
            path, "both four-point (p1x…p4z) and position/rotation columns: keep one",
            **header_place,
        )
    if present["points"]:
        return "points"
    if rotations:
        return rotations[0]
    raise WaypointFileError(
        path,
        f"cannot recognise the format from the columns {', '.join(header)}; expected "
        + "; ".join(f"{fmt}: {','.join(cols)}" for fmt, cols in FORMATS.items()),
        **header_place,
    )


def _check_columns(path: Path, header: list[str], columns: set[str], fmt: str,
                   extra_columns: tuple[str, ...], header_place: dict) -> None:
    """Every column of ``fmt`` is present, and no column is neither its own, ``name``,
    a caller's extra column nor (four-point files) a, b, c."""
    missing = [column for column in FORMATS[fmt] if column not in columns]
    if missing:
        raise WaypointFileError(
            path, f"{fmt} format: missing column{'s' * (len(missing) > 1)} "
            f"{', '.join(missing)}", **header_place,
        )
    allowed = set(FORMATS[fmt]) | {NAME, SEGMENT} | set(extra_columns)
    if fmt == "points":
        allowed |= set(ABC)
    unknown = [column for column in header if column not in allowed]
    if unknown:
        hint = " (a, b, c belong to the four-point format)" if set(unknown) & set(ABC) else ""
        raise WaypointFileError(
            path, f"unknown column{'s' * (len(unknown) > 1)} {', '.join(map(repr, unknown))}"
            f" in a {fmt} file{hint}", **header_place,
        )


def _check_abc_sources(path: Path, columns: set[str], fmt: str,
                       options: dict[str, float | None], header_place: dict) -> None:
    """The a=/b=/c= options only for four-point files, where each of a, b, c comes from
    exactly one place: its column or its option."""
    given = [key for key in ABC if options[key] is not None]
    if given and fmt != "points":
        raise WaypointFileError(
            path, f"option{'s' * (len(given) > 1)} {', '.join(given)} only apply to "
            "four-point files", **header_place,
        )
    if fmt != "points":
        return
    for key in ABC:
        if key in columns and options[key] is not None:
            raise WaypointFileError(
                path, f"{key} is given both as a column and as an option: keep one",
                **header_place,
            )
        if key not in columns and options[key] is None:
            raise WaypointFileError(
                path, f"four-point format: {key} (mm) is neither a column nor an option",
                **header_place,
            )


def _number(path: Path, value: object, column: str, where: dict) -> float:
    if isinstance(value, bool) or value is None:
        raise WaypointFileError(
            path, f"column {column}: expected a number, got {json.dumps(value)}", **where
        )
    if isinstance(value, int | float):  # JSON
        try:
            number = float(value)
        except OverflowError:
            problem = f"column {column}: {value} is too large"
            raise WaypointFileError(path, problem, **where) from None
    elif isinstance(value, str):
        if "line" not in where:  # JSON: numbers are numbers, not strings
            raise WaypointFileError(
                path, f"column {column}: expected a number, got the string {value!r}", **where
            )
        text = value.strip()
        if not text:
            raise WaypointFileError(path, f"column {column}: empty value", **where)
        if text.lower() in _NOT_FINITE:
            raise WaypointFileError(path, f"column {column}: {text} is not finite", **where)
        if not _NUMBER.fullmatch(text):
            raise WaypointFileError(
                path, f"column {column}: cannot parse {value!r} as a number", **where
            )
        number = float(text)
    else:
        raise WaypointFileError(
            path, f"column {column}: expected a number, got {type(value).__name__}", **where
        )
    if not math.isfinite(number):
        raise WaypointFileError(path, f"column {column}: {number} is not finite", **where)
    return number


def _text(path: Path, value: object, column: str, where: dict) -> str:
    if isinstance(value, str):
        return value.strip() if "line" in where else value
    raise WaypointFileError(
        path, f"column {column}: expected a string, got {type(value).__name__}", **where
    )


def _kuka_rotations(table: dict) -> np.ndarray:
    """R = Rz(A)·Ry(B)·Rx(C), the angles in degrees (KUKA's frames)."""
    a, b, c = (np.radians(table[key]) for key in KUKA_ANGLES)
    return rot_z(a) @ rot_y(b) @ rot_x(c)


def _quaternion_rotations(
    path: Path, table: dict, lines: tuple[int, ...], place: Callable[[int], dict],
    keys: tuple[str, ...] = QUATERNION,
) -> np.ndarray:
    w, x, y, z = (table[key] for key in keys)
    norm2 = w * w + x * x + y * y + z * z
    deviation = np.abs(np.sqrt(norm2) - 1.0)
    bad = np.flatnonzero(~(deviation <= QUATERNION_TOL))
    if bad.size:
        r = bad[0]
        raise WaypointFileError(
            path, f"quaternion norm {math.sqrt(norm2[r])!r} is not 1 within {QUATERNION_TOL:g}"
            " (quaternions are not normalised: write a unit quaternion)", **place(lines[r]),
        )
    return quaternion_matrix(np.stack([w, x, y, z], axis=-1))


def _matrix_rotations(
    path: Path, table: dict, lines: tuple[int, ...], place: Callable[[int], dict]
) -> np.ndarray:
    rotation = np.stack([table[key] for key in MATRIX], axis=-1).reshape(-1, 3, 3)
    error = np.abs(np.swapaxes(rotation, -1, -2) @ rotation - np.eye(3)).max(axis=(-2, -1))
    bad = np.flatnonzero(~(error <= ROTATION_TOL))
    if bad.size:
        r = bad[0]
        raise WaypointFileError(
            path, f"rotation matrix is not orthonormal: max |RᵀR − I| = {error[r]:.3g} > "
            f"{ROTATION_TOL:g}", **place(lines[r]),
        )
    det = np.linalg.det(rotation)
    bad = np.flatnonzero(det <= 0.0)
    if bad.size:
        raise WaypointFileError(
            path, f"rotation matrix has det {det[bad[0]]:.6g}: a reflection, not a rotation",
            **place(lines[bad[0]]),
        )
    return rotation


def _points_poses(
    path: Path,
    table: dict,
    options: dict,
    lines: tuple[int, ...],
    place: Callable[[int], dict],
) -> np.ndarray:
    n = len(lines)
    points_mm = np.stack([table[key] for key in POINTS], axis=-1).reshape(n, 4, 3)
    for key, value in options.items():
        if value is not None and not (math.isfinite(value) and value > 0):
            raise WaypointFileError(path, f"option {key} = {value!r} mm: must be positive")
    abc_mm = np.stack(
        [table[key] if key in table else np.full(n, float(options[key])) for key in ABC],
        axis=-1,
    )
    bad = np.flatnonzero(np.any(abc_mm <= 0.0, axis=-1))
    if bad.size:
        r = bad[0]
        k = int(np.argmax(abc_mm[r] <= 0.0))
        raise WaypointFileError(
            path, f"column {ABC[k]}: {float(abc_mm[r, k])!r} mm must be positive",
            **place(lines[r]),
        )
    # Millimetres to metres at the boundary, exactly as envs.kinematics.paper_example does.
    points, abc = points_mm / 1000.0, abc_mm / 1000.0
    poses = np.empty((n, 4, 4))
    for r in range(n):
        try:
            poses[r] = pose_from_points(points[r], *abc[r])
        except ValueError as exc:
            raise WaypointFileError(
                path, "four points inconsistent with a, b, c = "
                f"{', '.join(map(repr, abc_mm[r].tolist()))} mm: {exc}", **place(lines[r]),
            ) from None
    return poses


# ------------------------------------------------------------------------------- writing
def write_waypoints(
    path: str | os.PathLike,
    poses: ArrayLike,
    names: Sequence[str] | None = None,
    format: str = "matrix",
) -> Path:
    """Write ``poses`` (N, 4, 4) in metres as CSV or JSON (by ``path``'s suffix).

    ``format`` "matrix" (default) stores every float with its shortest round-trip repr, so
    ``read_waypoints(path).poses`` equals ``poses`` bit for bit. "quaternion" converts each
    rotation to a unit quaternion (qw ≥ 0); reading it back reproduces the rotation to
    rounding (~1e-16), not bit for bit. The poses are checked as the reader checks them
    (finite, bottom row exactly (0, 0, 0, 1), rotation within ``ROTATION_TOL``) before
    anything is written, and the file appears at once (written beside it, then renamed):
    nothing half-written. Returns the path.
    """
    path = Path(path)
    kind = _kind(path)
    if format not in ("matrix", "quaternion"):
        raise ValueError(f"format must be 'matrix' or 'quaternion', got {format!r}")
    poses = _checked_poses(poses)
    if names is not None:
        names = [str(name) for name in names]
        if len(names) != len(poses):
            raise ValueError(f"{len(names)} names for {len(poses)} poses")
    columns = FORMATS[format]
    rows = [_pose_numbers(pose, format) for pose in poses]
    if kind == "csv":
        text = _csv_text(columns, names, rows)
    else:
        text = _json_text(columns, names, rows)
    write_atomically(path, text)
    return path


def _checked_poses(poses: ArrayLike) -> np.ndarray:
    """``poses`` as a float (N, 4, 4) array, N ≥ 1, each checked as the reader checks it:
    finite, bottom row exactly (0, 0, 0, 1), rotation within ``ROTATION_TOL``."""
    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) == 0:
        raise ValueError(f"poses must have shape (N, 4, 4) with N ≥ 1, got {poses.shape}")
    for i, pose in enumerate(poses):
        if not np.all(np.isfinite(pose)):
            raise ValueError(f"pose {i} contains NaN or inf")
        if not np.array_equal(pose[3], (0.0, 0.0, 0.0, 1.0)):
            raise ValueError(f"pose {i}: bottom row must be (0, 0, 0, 1), got {pose[3]}")
        rotation = pose[:3, :3]
        error = np.abs(rotation.T @ rotation - np.eye(3)).max()
        if not error <= ROTATION_TOL or np.linalg.det(rotation) <= 0:
            raise ValueError(f"pose {i}: rotation block is not a rotation (|RᵀR − I| = "
                             f"{error:.3g}, tolerance {ROTATION_TOL:g})")
    return poses


def _pose_numbers(pose: np.ndarray, format: str) -> list[float]:
    """One file row's numbers (without the name) for ``pose`` in ``format``: the
    position, then the rotation by rows ("matrix") or as a unit quaternion."""
    if format == "matrix":
        numbers = [*pose[:3, 3], *pose[:3, :3].ravel()]
    else:
        numbers = [*pose[:3, 3], *rotation_to_quaternion(pose[:3, :3])]
    return [float(value) for value in numbers]


def _csv_text(columns: tuple[str, ...], names: list[str] | None,
              rows: list[list[float]]) -> str:
    """The CSV file: a header row, then one row per pose, floats as shortest repr."""
    header = ([NAME] if names is not None else []) + list(columns)
    buffer = io.StringIO(newline="")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for i, row in enumerate(rows):
        writer.writerow(([names[i]] if names is not None else []) + [repr(v) for v in row])
    return buffer.getvalue()


def _json_text(columns: tuple[str, ...], names: list[str] | None,
               rows: list[list[float]]) -> str:
    """The JSON file: a list of one object per pose (``name`` first when given)."""
    entries = [
        ({NAME: names[i]} if names is not None else {}) | dict(zip(columns, row, strict=True))
        for i, row in enumerate(rows)
    ]
    return json.dumps(entries, indent=1, allow_nan=False) + "\n"
