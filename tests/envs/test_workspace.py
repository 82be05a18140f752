"""The workspace tool: sampling, the voxel volume estimate, the picture and the CLI."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.rod import RodMechanism
from ikbranch_gym.envs.workspace import (
    limits_from_ranges,
    main,
    run,
    sample_joints,
    sample_workspace,
    voxel_volume,
)

ROOT = Path(__file__).resolve().parents[2]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
FULL = ((-np.pi, np.pi),) * 3


def rod_volume(q12_degrees, samples=60_000, seed=0):
    arm = RodMechanism()
    limits = np.array(arm.joint_limits)
    limits[1:] = np.radians([-q12_degrees, q12_degrees])
    points = sample_workspace(arm, samples, np.random.default_rng(seed), limits)
    return voxel_volume(points).volume


def test_cli_writes_a_png_and_reports_the_volume(tmp_path):
    out = tmp_path / "ws.png"
    result = subprocess.run(
        [sys.executable, "-m", "envs.workspace", "cylindrical4", "--out", str(out),
         "--samples", "20000", "--seed", "3", "--range", "phi1", "-90", "90",
         "--range", "s2", "300", "600"],
        cwd=ROOT, capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert out.read_bytes()[:8] == PNG_MAGIC
    assert "phi1 [-90, 90] deg" in result.stdout and "s2 [300, 600] mm" in result.stdout
    assert "volume ≈" in result.stdout and "voxel" in result.stdout


@pytest.mark.parametrize(
    "argv",
    [
        ["scara", "--out", "x.png"],
        ["cylindrical4", "--out", "x.png", "--range", "q9", "0", "1"],
        ["cylindrical4", "--out", "x.png", "--range", "phi1", "10", "-10"],
        ["cylindrical4", "--out", "x.png", "--samples", "0"],
        ["cylindrical4", "--out", "x.png", "--voxel", "-5"],
        ["cylindrical4", "--out", "x.png", "--voxel", "0.01"],
        ["cylindrical4", "--out", "x.png", "--range", "s1", "a", "b"],
    ],
)
def test_cli_rejects_bad_arguments(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert "error" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_cli_ranges_are_degrees_and_millimetres():
    arm = make_arm("cylindrical4")
    limits = limits_from_ranges(arm, [("phi1", -45.0, 30.0), ("s1", 400.0, 900.0)])
    np.testing.assert_allclose(limits[1], [-np.pi / 4, np.pi / 6])
    np.testing.assert_allclose(limits[0], [0.4, 0.9])
    np.testing.assert_array_equal(limits[2:], arm.joint_limits[2:])


def test_samples_are_seeded_and_within_the_limits():
    arm = RodMechanism()
    q = sample_joints(arm, 5000, np.random.default_rng(11))
    np.testing.assert_array_equal(q, sample_joints(arm, 5000, np.random.default_rng(11)))
    assert np.all(arm.within_limits(q))
    with pytest.raises(ValueError):
        sample_joints(arm, 10, np.random.default_rng(0), limits=[[0, 1]] * 2)


def test_narrower_ranges_give_a_smaller_workspace():
    volumes = [rod_volume(degrees) for degrees in (5, 10, 20, 30)]
    assert np.all(np.diff(volumes) > 0)
    # Halving both angular ranges shrinks the section in both directions: well under half.
    assert rod_volume(15) < 0.5 * rod_volume(30)


def test_volume_of_a_spherical_shell():
    """Rod mechanism with O1 on the axis (a = 0) and every joint turning fully: P sweeps the
    spherical shell between radii |b − l'p| and b + l'p around O1."""
    arm = RodMechanism(a=0.0, joint_limits=FULL)
    exact = 4 / 3 * np.pi * ((arm.b + arm.lp_prime) ** 3 - abs(arm.b - arm.lp_prime) ** 3)
    points = sample_workspace(arm, 200_000, np.random.default_rng(1))
    assert voxel_volume(points).volume == pytest.approx(exact, rel=0.08)


def test_volume_of_a_cylindrical_shell_sector():
    """cylindrical4: column s1, turn φ1, radius s2 sweep a sector of a hollow cylinder."""
    arm = make_arm("cylindrical4")
    (z0, z1), (p0, p1), (r0, r1) = arm.joint_limits[0], arm.joint_limits[1], arm.joint_limits[2]
    exact = (p1 - p0) / 2 * (r1**2 - r0**2) * (z1 - z0)
    points = sample_workspace(arm, 100_000, np.random.default_rng(2))
    estimate = voxel_volume(points)
    assert estimate.volume == pytest.approx(exact, rel=0.05)
    assert estimate.volume_half == pytest.approx(estimate.volume, rel=0.1)


def test_voxel_volume_of_a_uniform_ball():
    rng = np.random.default_rng(5)
    direction = rng.normal(size=(100_000, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    points = direction * 0.3 * np.cbrt(rng.uniform(size=(100_000, 1)))
    exact = 4 / 3 * np.pi * 0.3**3
    assert voxel_volume(points).volume == pytest.approx(exact, rel=0.05)
    # Counting every occupied cube, with no surface correction, overstates.
    estimate = voxel_volume(points)
    assert estimate.occupied * estimate.edge**3 > exact
    with pytest.raises(ValueError):
        voxel_volume(points, edge=0.0)


def test_run_accepts_an_arm_instance(tmp_path):
    out = tmp_path / "rod.png"
    estimate = run(RodMechanism(), out, samples=20_000, seed=0)
    assert out.read_bytes()[:8] == PNG_MAGIC
    assert estimate.volume > 0 and estimate.edge > 0
