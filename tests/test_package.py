"""The package as users get it: one import name, optional extras, a wheel that installs.

``ikbranch_gym`` is the only import name (its folder links the top-level ``envs/``,
``agents/``, ``train/`` and ``configs/``), so a user's own folders of those names shadow
nothing; the environments need gymnasium, mujoco, numpy and numba only.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import textwrap
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Top-level names of the folders ``ikbranch_gym`` links: nothing may load under them.
FOLDERS = ("envs", "agents", "train", "configs")
#: What ``pip install ikbranch-gym`` (no extra) brings: the environments' needs.
CORE = {"numpy", "gymnasium", "mujoco", "numba"}


def _python(code: str, cwd: Path, python: str = sys.executable, timeout: float = 600,
            env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": "egl", **(env or {})}
    env.pop("PYTHONPATH", None)
    return subprocess.run([python, "-c", textwrap.dedent(code)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def _user_folder(tmp_path: Path) -> Path:
    """A user's project with its own ``envs``, ``agents`` and ``train`` packages."""
    user = tmp_path / "user"
    for name in ("envs", "agents", "train"):
        (user / name).mkdir(parents=True)
        (user / name / "__init__.py").write_text(f"OWNER = 'user {name}'\n")
    return user


def test_the_core_dependencies_are_the_environments_only():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = {spec.split(">")[0].split("<")[0].split("[")[0] for spec in project["dependencies"]}
    assert names == CORE
    extras = project["optional-dependencies"]
    assert {"train", "sweep", "plan", "all", "dev"} <= set(extras)
    assert any(spec.startswith("torch") for spec in extras["train"])
    assert any(spec.startswith("ray[tune]") for spec in extras["sweep"])
    assert any(spec.startswith("coacd") for spec in extras["plan"])


def test_every_package_folder_ships_in_the_wheel():
    # setuptools is given the package list by hand (the folders are links): a new
    # subpackage missing from it would be left out of the wheel silently.
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "packages"])
    found = {"ikbranch_gym"}
    for folder in FOLDERS:
        for init in (ROOT / folder).rglob("__init__.py"):
            parts = init.parent.relative_to(ROOT).parts
            found.add(".".join(("ikbranch_gym", *parts)))
    data = {"ikbranch_gym.configs"}  # the hyper-parameters: a folder of data, no code
    assert data <= listed
    assert found == listed - data, (sorted(found - listed), sorted(listed - data - found))


def test_nothing_loads_under_a_bare_folder_name(tmp_path):
    # Every module of the package imported: each exists once, under ikbranch_gym only.
    result = _python(f"""
        import importlib, pkgutil, sys
        import ikbranch_gym
        for info in pkgutil.walk_packages(ikbranch_gym.__path__, "ikbranch_gym."):
            if not info.name.endswith("__main__"):
                importlib.import_module(info.name)
        print(sorted(m for m in sys.modules if m.partition(".")[0] in {FOLDERS!r}))
        print(len([m for m in sys.modules if m.startswith("ikbranch_gym.")]))
    """, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    bare, count = result.stdout.split("\n")[-3:-1]
    assert bare == "[]"
    assert int(count) > 60


def test_a_users_own_envs_agents_and_train_shadow_nothing(tmp_path):
    # Every id made from the user's folder (cwd first on sys.path), with the user's own
    # ``envs``, ``agents`` and ``train`` imported first; a committed model that pickled
    # its policy under the package's former import name loads, and the user's ``agents``
    # is still theirs afterwards.
    model = ROOT / "models" / "UR5e-v0" / "maskable_ppo.zip"
    result = _python(f"""
        import envs, agents, train
        import gymnasium as gym
        import ikbranch_gym
        from ikbranch_gym.agents.sb3 import SB3Policy
        for env_id in ikbranch_gym.ENV_IDS:
            env = gym.make(env_id, n_waypoints=2)
            _, info = env.reset(seed=0)
            env.step(int(info["action_mask"].argmax()))
        env = gym.make("IKBranch/UR5e-v0")
        obs, info = env.reset(seed=0)
        policy = SB3Policy.load({str(model)!r}, env)
        action, _ = policy.predict(obs, action_masks=info["action_mask"])
        assert info["action_mask"][int(action)]
        import sys
        print(envs.OWNER, agents.OWNER, train.OWNER, sys.modules["agents"].OWNER,
              "agents.branch_policy" in sys.modules, type(policy.model.policy).__module__)
    """, cwd=_user_folder(tmp_path))
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == [
        "user", "envs", "user", "agents", "user", "train", "user", "agents", "False",
        "ikbranch_gym.agents.branch_policy"]


def test_without_an_extra_a_command_says_which_to_install(tmp_path, monkeypatch, capsys):
    from ikbranch_gym.train import cli

    def missing(name):
        raise ModuleNotFoundError("No module named 'torch'", name="torch")

    monkeypatch.setattr(cli.importlib, "import_module", missing)
    assert cli.main(["train", "--help"]) == 2
    assert "pip install 'ikbranch-gym[train]'" in capsys.readouterr().err
    assert cli.main(["sweep"]) == 2
    assert "pip install 'ikbranch-gym[sweep]'" in capsys.readouterr().err


def _copy_sources(target: Path) -> Path:
    """The working tree's files a wheel is built from (links kept), outside the checkout:
    building writes ``build/`` beside the sources."""
    top = {".git", ".venv", "build", "runs", "models", "docs", "tests", "benchmarks",
           "examples"}

    def ignore(directory: str, names: list[str]) -> set[str]:
        skipped = {n for n in names if n == "__pycache__" or n.endswith((".egg-info", "_cache"))}
        return skipped | (top & set(names) if Path(directory) == ROOT else set())

    shutil.copytree(ROOT, target, symlinks=True, ignore=ignore)
    return target


def _shared_kernel_cache(root: Path) -> Path:
    """A ``NUMBA_CACHE_DIR`` holding this session's kernel caches (the env's, the IK
    driver's and the DP oracle's), linked: whatever sources share them find their kernels
    there."""
    from ikbranch_gym.agents import dp
    from ikbranch_gym.envs import jit
    from ikbranch_gym.envs.kinematics import compiled

    root.mkdir()
    for directory in (jit.cache_directory(), compiled.cache_directory(),
                      dp.cache_directory()):
        assert directory is not None, "no writable kernel cache in this session"
        (root / Path(directory).name).symlink_to(directory)
    return root


def test_the_wheel_installs_into_a_fresh_venv_with_core_extras_then_trains(tmp_path):
    # Built from the sources, installed outside the repository: gym.make and steps with the
    # core dependencies only (none of the extras' packages present), from a folder with
    # its own ``envs``; then ``[train]`` on top: the console command, and a tiny training
    # run whose hyper-parameters come from the package data.
    source = _copy_sources(tmp_path / "src")
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                    "--no-build-isolation", str(source), "-w", str(dist)], check=True,
                   capture_output=True, timeout=300)
    (wheel,) = dist.glob("ikbranch_gym-*.whl")
    venv = tmp_path / "venv"
    # Without a pip of its own (bootstrapping one is most of a venv's creation): the pip
    # of the Python running the tests installs into it (``--python``), as its own would.
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True,
                   timeout=300)
    python = str(venv / "bin" / "python")
    pip = [sys.executable, "-m", "pip", "--python", python]
    subprocess.run([*pip, "install", "--quiet", "--no-compile", str(wheel)], check=True,
                   capture_output=True, timeout=600)
    user = _user_folder(tmp_path)
    # The installed sources are this checkout's: with the test session's kernel caches
    # shared, the install loads every kernel instead of compiling it (three minutes), and
    # that is checked too. Compiling from nothing is what every fresh clone's warm-up does.
    shared = {"NUMBA_CACHE_DIR": str(_shared_kernel_cache(tmp_path / "numba"))}
    result = _python("""
        import envs, sys
        import gymnasium as gym
        env = gym.make("ikbranch_gym:IKBranch/ToolTransfer-v1")  # the id trained below
        obs, info = env.reset(seed=0)
        for _ in range(4):
            obs, reward, terminated, truncated, info = env.step(
                int(info["action_mask"].argmax()))
            if terminated or truncated:
                obs, info = env.reset()
        import ikbranch_gym
        from ikbranch_gym.envs import stepping
        from ikbranch_gym.envs.kinematics.compiled import compiled_solve_poses
        from ikbranch_gym.envs.models.filter.lanes import library  # its C source ships
        print(envs.OWNER, ikbranch_gym.__version__, ikbranch_gym.__file__.startswith(sys.prefix),
              library() is not None)
        print(sorted(m for m in ("torch", "stable_baselines3", "ray", "yaml", "coacd",
                                 "matplotlib", "rliable", "pandas") if m in sys.modules))
        from ikbranch_gym.agents import dp
        dp.warm_up()
        kernels = (stepping.survey, stepping.advance, compiled_solve_poses(), dp._backward)
        print(*(sum(sum(getattr(kernel.stats, kind).values()) for kernel in kernels)
                for kind in ("cache_hits", "cache_misses")))
    """, cwd=user, python=python, env=shared)
    assert result.returncode == 0, result.stderr
    first, second, third = result.stdout.strip().splitlines()[-3:]
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert first.split() == ["user", "envs", version, "True", "True"]
    assert second == "[]"
    assert third.split() == ["4", "0"], "the install compiled kernels its sources share"
    for name in ("torch", "stable_baselines3", "ray", "coacd"):
        probe = _python(f"import {name}", cwd=user, python=python)
        assert probe.returncode != 0, f"{name} was installed without its extra"
    console = str(venv / "bin" / "ikbranch")
    needs = subprocess.run([console, "train", "--help"], capture_output=True, text=True,
                           cwd=user, timeout=300)
    assert needs.returncode == 2 and "ikbranch-gym[train]" in needs.stderr
    # Compiling ahead of time needs nothing beyond the environments' own packages.
    ready = subprocess.run([console, "warm-up", "--processes", "1"], capture_output=True,
                           text=True, cwd=user, timeout=600,
                           env={**os.environ, "MUJOCO_GL": "egl", **shared})
    assert ready.returncode == 0 and "kernels ready in" in ready.stdout, ready.stderr

    # Then [train] on top. Its packages (torch's CPU build and the rest) are the ones this
    # test session runs on: the fresh venv sees them through a path file, so pip resolves
    # the extra's requirements against them and installs nothing (the Makefile's install
    # of .[dev] is where they are fetched); installing ~1 GB again here cost a minute.
    site = next(Path(venv, "lib").glob("python3*/site-packages"))
    ours = Path(sysconfig.get_paths()["purelib"])
    (site / "zz_test_session_packages.pth").write_text(f"{ours}\n")
    installed = subprocess.run([*pip, "install", f"{wheel}[train]"], check=True,
                               capture_output=True, text=True, timeout=900)
    fetched = " ".join(line for line in installed.stdout.splitlines()
                       if line.startswith("Successfully installed"))
    assert not any(name in fetched for name in ("torch", "stable-baselines3", "sb3-contrib")), (
        fetched)
    helped = subprocess.run([console, "train", "--help"], capture_output=True, text=True,
                            cwd=user, timeout=300)
    assert helped.returncode == 0 and "--algo" in helped.stdout, helped.stderr
    trained = subprocess.run(
        [console, "train", "--algo", "maskable_ppo", "--env", "IKBranch/ToolTransfer-v1",
         "--timesteps", "64", "--n-envs", "1", "--run-dir", "run", "--no-progress",
         "--hyperparams", '{"n_steps": 32, "batch_size": 32, "n_epochs": 1}'],
        capture_output=True, text=True, cwd=user, timeout=600,
        env={**os.environ, "MUJOCO_GL": "egl", **shared})
    assert trained.returncode == 0, trained.stderr
    assert (user / "run" / "model.zip").is_file()
    config = (user / "run" / "config.yml").read_text()
    # The run's recorded settings are the shipped file's entry for the id.
    assert "gamma" in config and "ToolTransfer-v1" in config
