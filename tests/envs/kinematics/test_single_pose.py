"""The compiled single-pose path (``envs/kinematics/compiled.py``) against the numpy solvers.

One mechanism serves every arm: a bare (4, 4) pose goes through the arm's scalar kernel,
compiled by numba, and the shared checks and limit/turn reduction. It must give the same
branches as ``ik_batched`` (the numpy reference). Bit for bit wherever both run the same
arithmetic: with numpy's own SIMD transcendentals switched off (its float64 arctan2/arccos
loops for AVX-512 differ from the C library's, which numba and ``math`` call, by an ulp on a
few percent of inputs), every arm whose numpy solver does not go through matmul/einsum
agrees exactly (``test_with_numpys_simd_transcendentals_off_…``). In the default numpy
build the values agree to 1e-12 and the validity exactly; where a value sits on the wrap
cut ±π of a seed joint, an ulp decides between −π and π (the same joint angle in the seeds'
[−π, π) convention); that is the one difference allowed.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from envs.kinematics import ARM_NAMES, make_arm
from envs.kinematics import compiled as compiled_module
from envs.kinematics.arm import WRAPPED, WRAPPED_FULL
from envs.kinematics.compiled import single_pose_solver

SPECIAL = np.array([0.0, np.pi / 2, -np.pi / 2, np.pi, -np.pi, 1e-9, -1e-13])


def awkward_configurations(arm, n=400, seed=17):
    """Random configurations, many with joints at 0, ±π/2, ±π, tiny angles (singular sets
    of most arms) or on a joint limit, clipped into the limits."""
    rng = np.random.default_rng(seed)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    q = rng.uniform(lower, upper, (n, arm.dof))
    revolute = arm.revolute_mask
    special = rng.random((n, arm.dof)) < 0.3
    q = np.where(special & revolute, rng.choice(SPECIAL, (n, arm.dof)), q)
    on_limit = rng.random((n, arm.dof)) < 0.05
    q = np.where(on_limit, np.where(rng.random((n, arm.dof)) < 0.5, lower, upper), q)
    return np.clip(q, lower, upper)


def target_poses(arm):
    pose = arm.fk(awkward_configurations(arm))
    far = pose[:5].copy()
    far[:, :3, 3] += 50.0  # unreachable
    return np.concatenate([pose, far])


def assert_same_branches(arm, pose, single, single_ok, batched, batched_ok) -> bool:
    """True if the rows agree to 1e-12; False if they differ more but both reproduce the
    pose to 1e-12 (an ill-conditioned closed form amplifying the ulp differences)."""
    np.testing.assert_array_equal(single_ok, batched_ok)
    assert np.all(np.isnan(single[~single_ok]))
    gap = np.abs(single[single_ok] - batched[batched_ok])
    wrapped = np.array([mode in (WRAPPED, WRAPPED_FULL) for mode, *_ in arm._joint_modes])
    on_cut = wrapped & (np.abs(np.abs(batched[batched_ok]) - np.pi) < 1e-12)
    gap = np.where(on_cut, np.minimum(gap, np.abs(gap - 2 * np.pi)), gap)
    if gap.size == 0 or gap.max() <= 1e-12:
        return True
    part = (lambda p: p[..., :3, 3]) if arm.target == "position" else (lambda p: p)
    for rows in (single[single_ok], batched[batched_ok]):
        assert np.abs(part(arm.fk(rows)) - part(pose)).max() < 1e-12, gap.max()
    return False


@pytest.mark.parametrize("name", ARM_NAMES)
def test_compiled_single_pose_path_agrees_with_the_numpy_solver(name):
    arm = make_arm(name)
    assert arm._single_pose_solver is not None, "numba is a dependency: the path must exist"
    poses = target_poses(arm)
    batched, batched_ok = arm.ik_batched(poses)
    ill_conditioned = 0
    for pose, expected, expected_ok in zip(poses, batched, batched_ok, strict=True):
        single, single_ok = arm.ik(pose)
        assert single.shape == (arm.n_branches, arm.dof) and single_ok.shape == (arm.n_branches,)
        ill_conditioned += not assert_same_branches(
            arm, pose, single, single_ok, expected, expected_ok
        )
    # Only at degenerate inputs (here: dual_rrp_rpp with phi2 = phi6 = 1e-9, its slide s3
    # nearly parallel to the plane it must cross, s3 = gap / 1e-17).
    assert ill_conditioned <= 0.01 * len(poses)


@pytest.mark.parametrize("name", ["anthropomorphic", "dual_rrp_rpp", "kuka_kr6_r700", "ur5e"])
def test_kernels_are_plain_python(name):
    """The kernel numba compiles is the same function run by CPython (no numba-only code):
    its raw rows from the interpreter equal the compiled path's after the same reduction."""
    arm = make_arm(name)
    kernel, params = type(arm)._kernel, arm._kernel_parameters()
    modes = [mode for mode, *_ in arm._joint_modes]
    lower = [low for _, low, _, _ in arm._joint_modes]
    upper = [high for _, _, high, _ in arm._joint_modes]
    slots = [count for *_, count in arm._joint_modes]
    for pose in target_poses(arm)[::20]:
        raw = np.full((arm.n_closed_form, arm.dof), np.nan)
        kernel(pose, params, raw)  # interpreted
        q = np.empty((arm.n_branches, arm.dof))
        ok = np.zeros(arm.n_branches, dtype=bool)
        compiled_module.finish_rows(raw, modes, lower, upper, slots, q, ok)  # interpreted
        single, single_ok = arm.ik(pose)  # compiled
        np.testing.assert_array_equal(ok, single_ok)
        np.testing.assert_allclose(q, single, rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", ["cartesian", "rod_mechanism", "opw", "ur10e"])
def test_single_pose_path_rejects_bad_input_like_the_numpy_path(name):
    arm = make_arm(name)
    pose = arm.fk(arm.home)
    cases = [
        (np.where(np.eye(4, dtype=bool), np.inf, pose), "NaN or inf"),
        (pose + np.array([[0, 0, 0, 0]] * 3 + [[0, 0, 0.5, 0]]), "bottom row"),
    ]
    if arm.target == "pose":
        cases += [
            (pose * np.array([1, 1, 1.01, 1])[:, None], "not orthonormal"),
            (pose @ np.diag([-1.0, 1.0, 1.0, 1.0]), "reflection"),
        ]
    for bad, message in cases:
        with pytest.raises(ValueError, match=message):
            arm.ik(bad)
        with pytest.raises(ValueError, match=message):
            arm.ik_batched(bad)


def test_other_dtypes_and_layouts_take_the_same_path():
    arm = make_arm("kuka_kr6_r700")
    pose = arm.fk(arm.home)
    reference = arm.ik(pose)
    for variant in (np.asfortranarray(pose), pose.astype(np.float32).astype(np.float64),
                    np.round(pose * 0).astype(int) + np.eye(4, dtype=int)):
        q, ok = arm.ik(variant)
        expected = arm.ik_batched(variant[None].astype(np.float64))
        np.testing.assert_array_equal(ok, expected[1][0])
        np.testing.assert_allclose(q, expected[0][0], rtol=0, atol=1e-12)
    assert reference[1].any()


def test_without_numba_single_poses_use_the_numpy_solver(monkeypatch):
    monkeypatch.setattr(compiled_module, "_numba", lambda: None)
    compiled_module._driver.cache_clear()
    try:
        arm = make_arm("ur5e")
        assert single_pose_solver(arm) is None
        pose = arm.fk(arm.home)
        q, ok = arm.ik(pose)
        expected_q, expected_ok = arm.ik_batched(pose[None])
        np.testing.assert_array_equal(q, expected_q[0])
        np.testing.assert_array_equal(ok, expected_ok[0])
    finally:
        compiled_module._driver.cache_clear()


def test_arms_pickle_after_a_single_pose_call():
    import pickle

    arm = make_arm("abb_irb2600")
    arm.ik(arm.fk(arm.home))
    again = pickle.loads(pickle.dumps(arm))
    np.testing.assert_array_equal(again.ik(arm.fk(arm.home))[1], arm.ik(arm.fk(arm.home))[1])


#: Arms whose numpy solver multiplies rotations with matmul/einsum (their own summation
#: order and FMA): their kernels write the products out and agree to an ulp, not bitwise.
MATMUL_SOLVERS = ("cylindrical4", "dual_rrp_rpp", "dual_rrr_ppp", "dual_ppr_prr")
ROOT = Path(__file__).resolve().parents[3]
_BITWISE_SCRIPT = """
import json, numpy as np
from numpy.lib import introspect
from envs.kinematics import make_arm
from tests.envs.kinematics.test_single_pose import target_poses
names = {names!r}
current = {{f: info["current"] for f, sigs in introspect.opt_func_info(
    func_name="^(arctan2|arccos|sin|cos)$", signature="float64").items()
    for info in sigs.values()}}
differ = {{}}
for name in names:
    arm = make_arm(name)
    poses = target_poses(arm)
    batched, batched_ok = arm.ik_batched(poses)
    differ[name] = sum(
        not (np.array_equal(ok, expected_ok) and np.array_equal(q, expected, equal_nan=True))
        for (q, ok), expected, expected_ok in zip(map(arm.ik, poses), batched, batched_ok))
print(json.dumps({{"current": current, "differ": differ}}))
"""


@pytest.mark.parametrize("name", ARM_NAMES)
def test_a_poses_branches_do_not_depend_on_the_rest_of_its_batch(name):
    # The wrist solver once took cos/sin of atan2 for every pose of a batch holding one
    # wrist-singular pose (and the exact ratios otherwise): a pose's branches then moved by
    # an ulp with the company it was solved in.
    arm = make_arm(name)
    poses = target_poses(arm)
    batched, batched_ok = arm.ik_batched(poses)
    for pose, expected, expected_ok in zip(poses, batched, batched_ok, strict=True):
        alone, alone_ok = arm.ik_batched(pose[None])
        np.testing.assert_array_equal(alone_ok[0], expected_ok)
        np.testing.assert_array_equal(alone[0], expected)


def test_with_numpys_simd_transcendentals_off_the_compiled_path_is_bitwise_the_numpy_path():
    from numpy.lib import introspect

    # The dispatch targets above numpy's baseline that this machine offers these ufuncs
    # (none on a machine without AVX2): switched off in a fresh interpreter.
    targets = introspect.opt_func_info(func_name="^(arctan2|arccos|sin|cos)$",
                                       signature="float64")
    active = {target for sigs in targets.values() for info in sigs.values()
              for target in info["available"].split() if not target.startswith("baseline")}
    names = [name for name in ARM_NAMES if name not in MATMUL_SOLVERS]
    env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": " ".join(sorted(active)),
           "PYTHONPATH": str(ROOT)}
    result = subprocess.run([sys.executable, "-c", _BITWISE_SCRIPT.format(names=names)],
                            env=env, cwd=ROOT, capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert all(target.startswith("baseline") for target in report["current"].values()), report
    assert report["differ"] == dict.fromkeys(names, 0)
