"""The one IK mechanism (``envs/kinematics/compiled.py``): every arm's scalar kernel behind
one driver, compiled by numba, for one pose and for batches alike.

The kernels and the driver are plain Python: what numba compiles is what CPython runs, and
the two must agree bit for bit (both call the C library's ``atan2``, ``acos``, ``sqrt``).
Whether the branches are *right* is held elsewhere: FK round trips, completeness against a
numerical solver and the branch labels' geometry, per arm (``test_arms.py``, ``test_opw.py``,
``test_ur.py``, ``test_turns.py``, ``test_dual.py``, ...).
"""

from __future__ import annotations

import json
import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ikbranch_gym.envs.kinematics import ARM_NAMES, make_arm
from ikbranch_gym.envs.kinematics import compiled as compiled_module
from ikbranch_gym.envs.kinematics.compiled import (
    KERNELS,
    closed_form_rows,
    compiled_solve_poses,
    driver_arguments,
    kernel_number,
    solve_poses,
    source_digest,
)

ROOT = Path(__file__).resolve().parents[3]

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


@pytest.mark.parametrize("name", ARM_NAMES)
def test_the_compiled_driver_is_the_interpreted_one_bit_for_bit(name):
    arm = make_arm(name)
    poses = np.ascontiguousarray(target_poses(arm))
    number = kernel_number(type(arm))
    arguments = driver_arguments(arm)
    compiled = compiled_solve_poses()(number, poses, *arguments)
    interpreted = solve_poses(number, poses, *arguments)
    assert compiled is not solve_poses and compiled[3:] == interpreted[3:] == (-1, 0)
    for got, expected in zip(compiled[:3], interpreted[:3], strict=True):
        np.testing.assert_array_equal(got, expected)
    q, ok, reach = compiled[:3]
    assert ok.any() and not ok.all(), "the poses should include invalid branches"
    assert not ok[-5:].any()  # 50 m away: out of reach or outside the limits
    assert np.all(reach[ok.any(axis=1)]) and reach[:-5].all()  # FK poses have a closed form
    assert np.all(np.isnan(q[~ok])) and np.all(np.isfinite(q[ok]))


@pytest.mark.parametrize("name", ARM_NAMES)
def test_a_poses_branches_do_not_depend_on_the_rest_of_its_batch(name):
    # The batched numpy solvers of earlier versions once moved a pose's branches by an ulp
    # with the company it was solved in; one driver, pose by pose, must not.
    arm = make_arm(name)
    poses = target_poses(arm)
    batched, batched_ok = arm.ik(poses)
    reach = arm.reaches(poses)
    for index, (pose, expected, expected_ok) in enumerate(
            zip(poses, batched, batched_ok, strict=True)):
        for alone, alone_ok in (arm.ik(pose), tuple(a[0] for a in arm.ik(pose[None]))):
            np.testing.assert_array_equal(alone_ok, expected_ok)
            np.testing.assert_array_equal(alone, expected)
        assert arm.reaches(pose) == reach[index]


def test_closed_form_rows_runs_the_kernel_of_its_number():
    for name in ARM_NAMES:
        arm = make_arm(name)
        number = kernel_number(type(arm))
        assert KERNELS[number] is type(arm)._kernel
        params = arm._kernel_parameters()
        for pose in target_poses(arm)[::50]:
            direct = np.full((arm.n_closed_form, arm.dof), np.nan)
            KERNELS[number](pose, params, direct)
            dispatched = np.full_like(direct, np.nan)
            closed_form_rows(number, pose, params, dispatched)
            np.testing.assert_array_equal(dispatched, direct)
    assert len(set(KERNELS)) == len(KERNELS)


def test_an_arm_class_whose_kernel_is_not_registered_is_refused():
    class Unregistered(type(make_arm("cartesian"))):
        @staticmethod
        def _kernel(m, p, out):
            out[0, :] = 0.0

    arm = Unregistered()
    with pytest.raises(TypeError, match=r"not one of envs\.kinematics\.compiled\.KERNELS"):
        arm.ik(arm.fk(arm.home))


@pytest.mark.parametrize("name", ["cartesian", "rod_mechanism", "opw", "ur10e"])
def test_bad_poses_are_refused_alone_and_in_a_batch(name):
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
    else:  # a position target's rotation is not read
        assert arm.ik(pose * np.array([1, 1, 1.01, 1])[:, None])[1].any()
    for bad, message in cases:
        with pytest.raises(ValueError, match=message):
            arm.ik(bad)
        batch = np.stack([pose, pose, bad, pose])
        with pytest.raises(ValueError, match=f"{message}.*pose 2 of the batch"):
            arm.ik(batch)
        with pytest.raises(ValueError, match=message):
            arm.reaches(batch)
    with pytest.raises(ValueError, match="shape"):
        arm.ik(pose[:3])


def test_other_dtypes_and_layouts_give_the_same_answer():
    arm = make_arm("kuka_kr6_r700")
    pose = arm.fk(arm.home)
    reference_q, reference_ok = arm.ik(pose)
    assert reference_ok.any()
    for variant in (np.asfortranarray(pose), pose.tolist(), pose[None, None]):
        q, ok = arm.ik(variant)
        np.testing.assert_array_equal(np.reshape(ok, reference_ok.shape), reference_ok)
        np.testing.assert_array_equal(np.reshape(q, reference_q.shape), reference_q)
    integer = np.eye(4, dtype=int)
    np.testing.assert_array_equal(arm.ik(integer)[1], arm.ik(np.eye(4))[1])
    assert arm.reaches(pose).shape == arm.reaches(pose.tolist()).shape == ()
    assert arm.reaches(pose[None]).shape == (1,)


def test_frozen_poses_go_through_the_driver_the_warm_up_compiled():
    # A waypoint file's poses are read-only; numba would type them apart and compile the
    # driver a second time, outside the warm-up, on the first call.
    driver = compiled_solve_poses()
    arm = make_arm("anthropomorphic")
    poses = arm.fk(np.random.default_rng(5).uniform(*arm.joint_limits.T, size=(6, arm.dof)))
    reference = arm.ik(poses), arm.ik(poses[0])
    compiled = list(driver.signatures)
    frozen = poses.copy()
    frozen.flags.writeable = False
    for got, want in zip((arm.ik(frozen), arm.ik(frozen[0])), reference, strict=True):
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)
    assert driver.signatures == compiled
    assert not frozen.flags.writeable


def test_without_numba_the_same_functions_run_interpreted(monkeypatch):
    arm = make_arm("ur5e")
    poses = arm.fk(awkward_configurations(arm, n=20))
    expected_q, expected_ok = arm.ik(poses)
    monkeypatch.setattr(compiled_module, "_numba", lambda: None)
    compiled_solve_poses.cache_clear()
    try:
        assert compiled_solve_poses() is solve_poses
        q, ok = make_arm("ur5e").ik(poses)
    finally:
        compiled_solve_poses.cache_clear()
    np.testing.assert_array_equal(ok, expected_ok)
    np.testing.assert_array_equal(q, expected_q)


def test_arms_pickle_after_an_ik_call():
    arm = make_arm("abb_irb2600")
    pose = arm.fk(arm.home)
    q, ok = arm.ik(pose)
    again = pickle.loads(pickle.dumps(arm))
    np.testing.assert_array_equal(again.ik(pose)[0], q)
    np.testing.assert_array_equal(again.ik(pose)[1], ok)


def test_the_cache_is_named_by_every_source_of_the_package(tmp_path):
    package = Path(compiled_module.__file__).parent
    copy = tmp_path / "kinematics"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert source_digest(copy) == source_digest(package)
    # An edited kernel in another file than the driver's: numba alone would not notice.
    opw = copy / "opw.py"
    opw.write_text(opw.read_text() + "\n")
    assert source_digest(copy) != source_digest(package)


_LOAD_SCRIPT = """
import json, time
start = time.perf_counter()
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.kinematics.compiled import compiled_solve_poses
arm = make_arm("opw")
arm.ik(arm.fk(arm.home))
stats = compiled_solve_poses().stats
print(json.dumps({"hits": sum(stats.cache_hits.values()),
                  "misses": sum(stats.cache_misses.values()),
                  "seconds": time.perf_counter() - start}))
"""


def test_a_new_process_loads_the_compiled_driver_from_disk():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    reports = []
    for _ in range(2):  # the first may compile (a cold cache); the second must load
        result = subprocess.run([sys.executable, "-c", _LOAD_SCRIPT], env=env, cwd=ROOT,
                                capture_output=True, text=True, check=False)
        assert result.returncode == 0, result.stderr[-2000:]
        reports.append(json.loads(result.stdout.strip().splitlines()[-1]))
    assert reports[1]["hits"] == 1 and reports[1]["misses"] == 0, reports


_KERNEL_MODULE = """
def scaled(x):
    return 3.0 * x
"""


def _load_copy(folder: Path, name: str, text: str = _KERNEL_MODULE):
    # A kernel module at its own place, imported as a module of its own name.
    import importlib.util

    folder.mkdir(parents=True)
    path = folder / "kernel.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_cache_serves_the_same_sources_wherever_they_lie(tmp_path):
    # Two installs of one source (another checkout, another venv) share a cache
    # directory: the second loads what the first compiled, numba's own cache would not.
    cache = tmp_path / "cache"
    cache.mkdir()
    first = _load_copy(tmp_path / "one" / "pkg", "kernel_one")
    second = _load_copy(tmp_path / "two" / "pkg", "kernel_two")
    kernels = [compiled_module.cached_njit(module.scaled, cache, path.parent)
               for module, path in ((first, tmp_path / "one" / "pkg"),
                                    (second, tmp_path / "two" / "pkg"))]
    assert kernels[0](2.0) == 6.0
    assert sum(kernels[0].stats.cache_misses.values()) == 1
    assert kernels[1](2.0) == 6.0
    assert sum(kernels[1].stats.cache_hits.values()) == 1
    assert sum(kernels[1].stats.cache_misses.values()) == 0
    # The cache sits under the file's path relative to the root it was given.
    assert Path(kernels[1]._cache._cache_path) == cache / "pkg"
    # Another text, another stamp: an edited copy compiles afresh.
    third = _load_copy(tmp_path / "three" / "pkg", "kernel_three",
                       _KERNEL_MODULE.replace("3.0", "4.0"))
    edited = compiled_module.cached_njit(third.scaled, cache, tmp_path / "three")
    assert edited(2.0) == 8.0
    assert sum(edited.stats.cache_hits.values()) == 0


def test_without_numbas_cache_parts_the_kernels_keep_numbas_own_cache(tmp_path, monkeypatch):
    # A numba without the parts the portable cache is built from: its own cache, still in
    # the directory given, and numba's setting as it was.
    import numba

    monkeypatch.setattr(compiled_module, "_portable_cache", lambda directory, root: None)
    cache = tmp_path / "cache"
    cache.mkdir()
    module = _load_copy(tmp_path / "one" / "pkg", "kernel_fallback")
    before = numba.config.CACHE_DIR
    kernel = compiled_module.cached_njit(module.scaled, cache, tmp_path / "one")
    assert numba.config.CACHE_DIR == before
    assert kernel(2.0) == 6.0
    assert Path(kernel._cache._cache_path).parent == cache
    assert any(Path(kernel._cache._cache_path).glob("kernel.scaled-*.nbi"))


def test_the_cache_goes_where_numba_cache_dir_says(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    package = Path(compiled_module.__file__).parent
    directory = compiled_module.cache_directory()
    assert directory == tmp_path / f"numba-{source_digest(package)}" and directory.is_dir()
    # An unwritable root is passed over for the next one.
    blocked = tmp_path / "file"
    blocked.write_text("")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(blocked))
    assert compiled_module.cache_directory().parent != blocked
