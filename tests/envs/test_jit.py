"""The env's kernels are cached under a hash of every module they are compiled from."""

from __future__ import annotations

from pathlib import Path

import numba
import pytest

import ikbranch_gym.envs as envs
from ikbranch_gym.envs import jit

ROOT = Path(envs.__file__).resolve().parent


def test_every_module_that_compiles_kernels_is_hashed():
    hashed = {path.resolve() for path in jit._sources()}
    compiling = set()
    for path in ROOT.rglob("*.py"):
        if "kinematics" in path.relative_to(ROOT).parts or path.name == "jit.py":
            continue  # the IK driver has its own cache (envs.kinematics.compiled)
        text = path.read_text()
        if "njit" in text or "intrinsic" in text:
            compiling.add(path.resolve())
    assert compiling and compiling <= hashed, sorted(map(str, compiling - hashed))


def test_the_cache_directory_is_named_by_the_sources(tmp_path, monkeypatch):
    directory = jit.cache_directory()
    assert directory is not None and Path(directory).name.startswith("numba-")
    # Another source text, another directory: a kernel never loads code of an old helper.
    sources = [tmp_path / "a.py"]
    sources[0].write_text("x = 1\n")
    monkeypatch.setattr(jit, "_ROOT", tmp_path)
    monkeypatch.setattr(jit, "_sources", lambda: sources)
    jit.cache_directory.cache_clear()
    try:
        first = jit.cache_directory()
        sources[0].write_text("x = 2\n")
        jit.cache_directory.cache_clear()
        assert jit.cache_directory() != first
    finally:
        jit.cache_directory.cache_clear()


def test_kernels_are_cached_in_that_directory():
    from ikbranch_gym.envs.models.filter import kernels

    location = Path(kernels.check_paths._cache._cache_path).resolve()
    assert Path(jit.cache_directory()).resolve() in location.parents
    assert isinstance(kernels.check_paths, numba.core.registry.CPUDispatcher)


def test_single_and_vector_envs_and_frozen_rows_share_one_compiled_version():
    # Each extra argument type is every kernel compiled again (minutes on a fresh
    # install): a vector env's sub-env views must type as the batch does, and rows the
    # filter is handed read-only (an arm's frozen home) must reach the kernels writable.
    import gymnasium as gym

    from ikbranch_gym.envs import stepping
    from ikbranch_gym.envs.models.filter import kernels

    env_id = "IKBranch/Cartesian-v3"
    single = gym.make(env_id)
    single.reset(seed=0)
    vector = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
    vector.reset(seed=0)
    home = single.unwrapped.arm.home
    assert not home.flags.writeable
    single.unwrapped.checker.collides(home)
    single.unwrapped.compiled_filter.collide(home[None])
    assert len(stepping.make_episodes.signatures) == 1
    assert not any(signature[2].mutable is False
                   for signature in kernels.bound_configurations.signatures)
    single.close()
    vector.close()


def test_warm_up_takes_one_or_two_processes_and_known_parts():
    with pytest.raises(ValueError, match="processes must be 1 or 2"):
        envs.warm_up(processes=3)
    with pytest.raises(ValueError, match="no part 'everything'"):
        envs._warm_up_part("everything")
    for phase in envs.WARM_UP_PHASES:  # each part runs (here from the warm cache)
        for part in phase:
            envs._warm_up_part(part)
