"""Reachable workspace of an arm's output point: joint sampling, a volume estimate, a picture.

    python -m envs.workspace ARM --out FILE.png [--samples N] [--seed S]
                             [--range JOINT LO HI]... [--voxel MM]

Joint values are drawn uniformly within the joint limits (or the ``--range`` overrides) by
a seeded numpy Generator and mapped through ``arm.fk``; the translations are the sampled
workspace. ``--range`` takes the papers' units: degrees for revolute joints, millimetres
for prismatic ones; everything inside is SI.

Volume: voxel counting. The points are binned into cubes of edge h; by default h is the
longest side of their bounding box divided by ∛(N / ``SAMPLES_PER_CUBE``), about eight
samples per cube of the bounding box. Counting every occupied cube overstates the volume by
the cubes the surface only clips, so cubes with an empty face neighbour (the surface layer)
count half: V ≈ (n_inside + n_surface/2)·h³. Too few samples per cube leave holes and
understate: the estimate is repeated on every second sample with the same grid, and a
clear gap between the two says the sampling is too sparse for that h. Checked against
analytic volumes (a spherical shell, a cylindrical shell sector) to a few per cent.

The picture: a vertical section (points within h/2 of the vertical plane through the Z
axis and the home position, or the Y–Z plane when home is on the axis) and a 3-D view with
the quadrant facing the viewer cut away, so that hollows around the axis show.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ikbranch_gym.envs.kinematics import ARM_NAMES, Arm, make_arm
from ikbranch_gym.envs.kinematics.arm import REVOLUTE

#: Default voxel size: about this many samples per cube of the sampled bounding box. Fewer
#: leaves holes in sparsely sampled regions, more makes the cubes (and the error) coarse.
SAMPLES_PER_CUBE = 8
DEFAULT_SAMPLES = 200_000
#: Points drawn in the 3-D view: more only darkens the cloud and slows rendering.
MAX_3D_POINTS = 12_000
#: matplotlib's default 3-D camera azimuth (deg): the cut-away quadrant faces it.
VIEW_AZIMUTH = -60.0
#: Largest voxel grid (cubes) built: 64 MB of booleans; a finer --voxel is refused.
MAX_CUBES = 64_000_000
_MM = 1e-3


@dataclass(frozen=True)
class VolumeEstimate:
    volume: float  # m³
    edge: float  # voxel edge h, m
    occupied: int  # cubes holding at least one sample
    surface: int  # occupied cubes with an empty face neighbour (counted half)
    volume_half: float  # the same estimate from every second sample, same grid


def sample_joints(arm: Arm, n: int, rng: np.random.Generator,
                  limits: ArrayLike | None = None) -> np.ndarray:
    """(n, dof) joint values uniform within ``limits`` ((dof, 2), SI; default the arm's)."""
    limits = np.asarray(arm.joint_limits if limits is None else limits, dtype=np.float64)
    if limits.shape != (arm.dof, 2) or np.any(limits[:, 0] >= limits[:, 1]):
        raise ValueError(f"limits must be ({arm.dof}, 2) with lower < upper")
    return rng.uniform(limits[:, 0], limits[:, 1], size=(n, arm.dof))


def sample_workspace(arm: Arm, n: int, rng: np.random.Generator,
                     limits: ArrayLike | None = None) -> np.ndarray:
    """(n, 3) positions of the output point for ``n`` uniform joint samples."""
    return arm.positions(sample_joints(arm, n, rng, limits))


def default_voxel_edge(points: np.ndarray) -> float:
    """Voxel edge for about ``SAMPLES_PER_CUBE`` samples per cube of the bounding box."""
    cells = np.clip(np.cbrt(len(points) / SAMPLES_PER_CUBE), 4, 256)
    return float(np.max(np.ptp(points, axis=0))) / cells


def voxel_volume(points: np.ndarray, edge: float | None = None) -> VolumeEstimate:
    """Voxel-counting volume of a point cloud (see the module docstring)."""
    points = np.asarray(points, dtype=np.float64)
    edge = default_voxel_edge(points) if edge is None else float(edge)
    if not edge > 0.0:
        raise ValueError("voxel edge must be positive (and the points not all equal)")
    # Half a cube of slack below the lowest sample: a flat face there (a joint at its limit)
    # then cuts its cubes in half, as a generic surface does on average.
    cells = np.floor((points - points.min(axis=0)) / edge + 0.5).astype(np.int64)
    if np.prod(cells.max(axis=0) + 3, dtype=np.float64) > MAX_CUBES:
        raise ValueError(f"voxel edge {edge:g} m is too fine for this workspace")
    occupied, surface = _count_cubes(cells)
    half = _count_cubes(cells[::2])
    return VolumeEstimate(
        volume=(occupied - surface / 2) * edge**3,
        edge=edge,
        occupied=occupied,
        surface=surface,
        volume_half=(half[0] - half[1] / 2) * edge**3,
    )


def _count_cubes(cells: np.ndarray) -> tuple[int, int]:
    """Occupied cubes, and those of them with an empty face neighbour."""
    # A one-cube empty margin keeps every neighbour lookup (and np.roll's wrap) in the grid.
    grid = np.zeros(tuple(cells.max(axis=0) + 3), dtype=bool)
    grid[tuple((cells + 1).T)] = True
    core = grid[1:-1, 1:-1, 1:-1]
    enclosed = np.ones_like(core)
    for axis in range(3):
        for shift in (-1, 1):
            enclosed &= np.roll(grid, shift, axis=axis)[1:-1, 1:-1, 1:-1]
    return int(core.sum()), int((core & ~enclosed).sum())


def section_direction(arm: Arm) -> np.ndarray:
    """Horizontal unit vector spanning, with Z, the vertical section plane."""
    home = arm.fk(arm.home)[:2, 3]
    norm = np.hypot(*home)
    return home / norm if norm > 1e-9 else np.array([0.0, 1.0])


def plot_workspace(arm: Arm, points: np.ndarray, estimate: VolumeEstimate,
                   out: str | os.PathLike[str], title: str | None = None) -> None:
    """Write the section and 3-D view of ``points`` to ``out`` (a PNG path)."""
    # A bare Figure renders with Agg and leaves the caller's pyplot backend alone.
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    direction = section_direction(arm)
    across = points[:, 0] * -direction[1] + points[:, 1] * direction[0]
    slab = points[np.abs(across) <= estimate.edge / 2]
    along = slab[:, :2] @ direction
    dx, dy = np.round(direction, 2) + 0.0  # + 0.0 turns -0.0 into 0.0 for the label

    fig = Figure(figsize=(11, 5))
    ax = fig.add_subplot(1, 2, 1)
    ax.scatter(along, slab[:, 2], s=0.5, color="tab:blue", linewidths=0)
    ax.axvline(0.0, color="0.4", lw=0.8, ls="--", label="base axis Z")
    ax.set_aspect("equal")
    ax.set_xlabel(f"horizontal along ({dx:g}, {dy:g}, 0) [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(f"vertical section (|offset| ≤ {estimate.edge / 2 * 1e3:.0f} mm)")
    ax.legend(loc="best", fontsize="small")

    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    view = np.radians(VIEW_AZIMUTH)
    facing = (points[:, 0] * np.cos(view) > 0) & (points[:, 1] * np.sin(view) > 0)
    cloud = points[~facing]
    cloud = cloud[:: max(1, len(cloud) // MAX_3D_POINTS)]
    ax3.scatter(cloud[:, 0], cloud[:, 1], cloud[:, 2], s=0.5, c=cloud[:, 2], cmap="viridis")
    ax3.view_init(azim=VIEW_AZIMUTH)
    ax3.set_box_aspect(np.ptp(points, axis=0) + 1e-9)
    for axis, label in zip((ax3.xaxis, ax3.yaxis, ax3.zaxis), "xyz", strict=True):
        axis.set_major_locator(MaxNLocator(4))
        axis.set_label_text(f"{label} [m]")
    ax3.set_title("3-D view, quadrant towards the viewer cut away")
    fig.suptitle(title or f"{arm.name}: V ≈ {estimate.volume:.4g} m³")
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def limits_from_ranges(arm: Arm, ranges: Iterable[tuple[str, float, float]]) -> np.ndarray:
    """The arm's limits with ``ranges`` [(joint, lo, hi), …] in degrees / mm replacing them."""
    limits = np.array(arm.joint_limits, dtype=np.float64)
    for joint, lo, hi in ranges:
        if joint not in arm.joint_names:
            raise ValueError(f"{arm.name} has no joint {joint!r}: {', '.join(arm.joint_names)}")
        index = arm.joint_names.index(joint)
        unit = np.pi / 180.0 if arm.joint_types[index] == REVOLUTE else _MM
        if not lo < hi:
            raise ValueError(f"range of {joint} needs LO < HI, got {lo} {hi}")
        limits[index] = (lo * unit, hi * unit)
    return limits


def describe_limits(arm: Arm, limits: np.ndarray) -> str:
    parts = []
    for name, kind, (lo, hi) in zip(arm.joint_names, arm.joint_types, limits, strict=True):
        if kind == REVOLUTE:
            parts.append(f"{name} [{np.degrees(lo):g}, {np.degrees(hi):g}] deg")
        else:
            parts.append(f"{name} [{lo / _MM:g}, {hi / _MM:g}] mm")
    return ", ".join(parts)


def run(arm: Arm | str, out: str | os.PathLike[str], samples: int = DEFAULT_SAMPLES,
        seed: int = 0, limits: ArrayLike | None = None, edge: float | None = None,
        title: str | None = None) -> VolumeEstimate:
    """Sample, estimate and draw; returns the ``VolumeEstimate``. ``arm``: name or Arm."""
    arm = make_arm(arm) if isinstance(arm, str) else arm
    points = sample_workspace(arm, samples, np.random.default_rng(seed), limits)
    estimate = voxel_volume(points, edge)
    plot_workspace(arm, points, estimate, out, title)
    return estimate


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m envs.workspace", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("arm", help=f"one of: {', '.join(ARM_NAMES)}")
    parser.add_argument("--out", required=True, help="PNG file to write")
    parser.add_argument("--samples", type=int, default=DEFAULT_SAMPLES)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--range",
        nargs=3,
        action="append",
        default=[],
        metavar=("JOINT", "LO", "HI"),
        help="sample JOINT within [LO, HI] (degrees, or mm for a prismatic joint); repeatable",
    )
    parser.add_argument("--voxel", type=float, help="voxel edge in mm (default: auto)")
    args = parser.parse_args(argv)
    try:
        arm = make_arm(args.arm)
        ranges = [(joint, float(lo), float(hi)) for joint, lo, hi in args.range]
        limits = limits_from_ranges(arm, ranges)
        if args.samples < 1:
            raise ValueError("--samples must be positive")
        if args.voxel is not None and not args.voxel > 0.0:
            raise ValueError("--voxel must be positive")
        edge = None if args.voxel is None else args.voxel * _MM
        estimate = run(arm, args.out, args.samples, args.seed, limits, edge)
    except ValueError as exc:
        parser.error(str(exc))
    print(f"{arm.name}: {describe_limits(arm, limits)}")
    print(
        f"volume ≈ {estimate.volume:.6g} m³ (voxel counting, edge {estimate.edge / _MM:.3g} mm:"
        f" {estimate.occupied} occupied cubes, {estimate.surface} on the surface counted half;"
        f" {args.samples} samples, seed {args.seed})"
    )
    print(f"same grid, every second sample: {estimate.volume_half:.6g} m³ (sampling check)")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
