"""Train PPO, MaskablePPO or MaskablePPO after cloning the DP oracle (``bc_maskable_ppo``,
``train.imitation``) on a registered env, into a self-describing run directory.

Run directory layout::

    config.yml      resolved hyper-parameters, env kwargs and arguments
    command.txt     the command line that started (or resumed) the run
    versions.yml    python and package versions
    model.zip       the final model
    best/best_model.zip, best/best.json   best held-out evaluation so far
    checkpoints/ckpt_<steps>.zip, checkpoints/latest.zip   crash-safe checkpoints
    checkpoints/vecnormalize.pkl   reward statistics (with ``normalize_reward``), for resume
    evaluations.npz held-out evaluation history (the learning curve)
    imitation.json  bc_maskable_ppo: the oracle's episodes and steps, the fit
    tb/             TensorBoard logs
"""

from __future__ import annotations

import functools
import platform
import shlex
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import gymnasium as gym
import torch
import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import CallbackList
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecNormalize

from ikbranch_gym.agents.sb3 import load_model
from ikbranch_gym.envs.seeds import VALIDATION_OFFSET, held_out
from ikbranch_gym.train.callbacks import (
    LATEST,
    REWARD_STATS,
    AtomicCheckpointCallback,
    HeldOutEvalCallback,
    atomic_save,
)
from ikbranch_gym.train.hyperparams import (
    IMITATION_ALGORITHMS,
    RUN_KEYS,
    algorithm_class,
    check_algorithm,
    hyperparams_for,
    uses_masks,
)
from ikbranch_gym.train.vec_env import make_native_vec_env

VERSIONED = ("ikbranch-gym", "gymnasium", "mujoco", "numpy", "torch", "stable-baselines3",
             "sb3-contrib")


def make_env(env_id: str, env_kwargs: dict[str, Any]) -> gym.Env:
    """A top-level factory (picklable for subprocesses); importing ``envs`` registers ids."""
    import ikbranch_gym.envs  # noqa: F401

    return gym.make(env_id, **env_kwargs)


@dataclass
class RunConfig:
    algo: str
    env_id: str
    seed: int
    run_dir: Path
    timesteps: int | None = None
    n_envs: int | None = None
    config: str | None = None
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    hyperparams: dict[str, Any] = field(default_factory=dict)  # CLI overrides, win
    resume: bool = False
    progress_bar: bool = True
    verbose: int = 0
    #: The learner's torch threads. One is fastest here: the policy is a small MLP and, on a
    #: 2-core machine, a second thread only fights the env processes (10x slower measured).
    torch_threads: int = 1
    #: One of ``VEC_ENVS``: "native" (the default): the natively batched vector env, all
    #: n_envs in this process with no per-env loop (``train/vec_env.py``); "subproc": the
    #: single envs in worker processes; "dummy": the single envs one after another here.
    #: The three give the learner the same data (tested).
    vec_env: str = "native"
    #: The native vector env's threads (``envs.vector_env``): its sub-envs in this many
    #: groups stepped side by side; the same data whatever the number.
    env_threads: int = 1


#: The ways ``train`` runs its envs (``RunConfig.vec_env``).
VEC_ENVS = ("native", "subproc", "dummy")


def vec_envs(kind: str, env_id: str, env_kwargs: dict[str, Any], n_envs: int,
             seed: int, threads: int = 1) -> tuple[VecEnv, VecEnv]:
    """The training envs (``n_envs``, sub-env i seeded ``seed + i``; the native vector
    env's in ``threads`` threads) and the one held-out evaluation env, both of ``kind``
    (one of ``VEC_ENVS``)."""
    if kind not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {', '.join(map(repr, VEC_ENVS))}, got {kind!r}")
    if threads != 1 and kind != "native":
        raise ValueError(f"env threads ({threads}) are the native vector env's; vec_env "
                         f"{kind!r} runs single envs")
    evaluation = held_out(env_id, env_kwargs)
    eval_seed = seed + VALIDATION_OFFSET
    if kind == "native":
        return (make_native_vec_env(env_id, n_envs, env_kwargs, seed=seed, threads=threads),
                make_native_vec_env(env_id, 1, evaluation, seed=eval_seed))
    vec_env_cls = SubprocVecEnv if n_envs > 1 and kind == "subproc" else DummyVecEnv
    train_env = make_vec_env(functools.partial(make_env, env_id, env_kwargs), n_envs=n_envs,
                             seed=seed, vec_env_cls=vec_env_cls)
    eval_env = make_vec_env(functools.partial(make_env, env_id, evaluation), n_envs=1,
                            seed=eval_seed, vec_env_cls=vec_env_cls)
    return train_env, eval_env


def branch_policy(algo: str, factory: Callable[[], gym.Env],
                  overrides: dict[str, Any]) -> tuple[type, dict[str, Any]]:
    """``policy: BranchPolicy`` in a config: the class for ``algo`` and its policy_kwargs,
    built from the env's observation layout (``agents.branch_policy``)."""
    from ikbranch_gym.agents.branch_policy import (
        BranchPolicy,
        MaskableBranchPolicy,
        branch_policy_kwargs,
    )

    probe = factory()
    try:
        kwargs = branch_policy_kwargs(probe, **overrides)
    finally:
        probe.close()
    return (MaskableBranchPolicy if uses_masks(algo) else BranchPolicy), kwargs


def resolve(run: RunConfig) -> dict[str, Any]:
    """The entry of the YAML file with the CLI's overrides applied (CLI wins)."""
    params = hyperparams_for(run.env_id, run.algo, run.config)
    params.update(run.hyperparams)
    if run.timesteps is not None:
        params["n_timesteps"] = run.timesteps
    if run.n_envs is not None:
        params["n_envs"] = run.n_envs
    params["env_kwargs"] = {**params.get("env_kwargs", {}), **run.env_kwargs}
    for key in ("n_timesteps", "n_envs"):
        if not isinstance(params.get(key), int) or params[key] < 1:
            raise ValueError(f"{key} must be a positive integer, got {params.get(key)!r}")
    return params


def package_versions() -> dict[str, str]:
    versions = {"python": platform.python_version()}
    for name in VERSIONED:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions


def train(run: RunConfig, argv: list[str] | None = None) -> BaseAlgorithm:
    """Train (or resume) and return the model; everything lands in ``run.run_dir``."""
    check_algorithm(run.algo)
    params = resolve(run)
    torch.set_num_threads(run.torch_threads)
    run_dir = Path(run.run_dir)
    checkpoints = run_dir / "checkpoints"
    latest = checkpoints / LATEST
    if run.resume and not latest.exists():
        raise ValueError(f"--resume: no checkpoint at {latest}")
    if not run.resume and latest.exists():
        raise ValueError(f"{run_dir} already holds a run: pass --resume or another --run-dir")
    run_dir.mkdir(parents=True, exist_ok=True)
    _write_records(run, params, run_dir, argv)

    env_kwargs = params["env_kwargs"]
    n_envs = params["n_envs"]
    factory = functools.partial(make_env, run.env_id, env_kwargs)
    # The evaluation env: the same VecEnv class as training (SB3 warns otherwise), one env:
    # masks and seeds; scenes from the held-out range where the id draws one per episode
    # (envs/seeds.py).
    train_env, eval_env = vec_envs(run.vec_env, run.env_id, env_kwargs, n_envs, run.seed,
                                   run.env_threads)
    if params.get("normalize_reward", False):
        # Returns span −20 (a clean run) to −300 (an early crash): scaling the reward by
        # its running std keeps the value targets small and, measured on ToolTransfer-v0,
        # turns a policy collapsed onto one branch (74 % success at 40k steps) into one
        # that succeeds on every held-out task. Observations are already in [−1, 1].
        stats = checkpoints / REWARD_STATS
        if run.resume and stats.exists():
            train_env = VecNormalize.load(str(stats), train_env)
        else:
            train_env = VecNormalize(train_env, norm_obs=False, norm_reward=True,
                                     gamma=params.get("gamma", 0.99))
        # Evaluation sees the env's own rewards; SB3 wants the same wrapper type on both.
        eval_env = VecNormalize(eval_env, norm_obs=False, norm_reward=False, training=False)
    algo_kwargs = {key: value for key, value in params.items() if key not in RUN_KEYS}
    algorithm = algorithm_class(run.algo)
    try:
        if run.resume:
            model = load_model(algorithm, latest, env=train_env,
                               tensorboard_log=str(run_dir / "tb"))
        else:
            policy = params["policy"]
            if policy == "BranchPolicy":
                policy, algo_kwargs["policy_kwargs"] = branch_policy(
                    run.algo, factory, algo_kwargs.get("policy_kwargs") or {}
                )
            model = algorithm(
                policy, train_env, seed=run.seed, verbose=run.verbose,
                tensorboard_log=str(run_dir / "tb"), **algo_kwargs,
            )
            if run.algo in IMITATION_ALGORITHMS:
                from ikbranch_gym.train.imitation import warm_start

                demonstrator = factory()
                try:
                    normalizer = train_env if isinstance(train_env, VecNormalize) else None
                    warm_start(model, demonstrator, params, run.seed, normalizer, run_dir)
                finally:
                    demonstrator.close()
        per_env = lambda steps: max(1, steps // n_envs)  # noqa: E731 (callbacks count vec steps)
        checkpoint = AtomicCheckpointCallback(per_env(params["checkpoint_freq"]), checkpoints)
        evaluation = HeldOutEvalCallback(
            eval_env,
            eval_seed=run.seed + VALIDATION_OFFSET,
            resume=run.resume,
            n_eval_episodes=params["n_eval_episodes"],
            eval_freq=per_env(params["eval_freq"]),
            best_model_save_path=str(run_dir / "best"),
            log_path=str(run_dir),
            deterministic=True,
            use_masking=uses_masks(run.algo),
            verbose=run.verbose,
        )
        remaining = params["n_timesteps"] - model.num_timesteps
        if remaining > 0:
            model.learn(
                remaining,
                callback=CallbackList([checkpoint, evaluation]),
                reset_num_timesteps=not run.resume,
                progress_bar=run.progress_bar,
                tb_log_name="run",
            )
        checkpoint.save()
        atomic_save(model, run_dir / "model.zip")
    finally:
        train_env.close()
        eval_env.close()
    return model


def _write_records(run: RunConfig, params: dict, run_dir: Path, argv: list[str] | None) -> None:
    config = {
        "algo": run.algo,
        "env_id": run.env_id,
        "seed": run.seed,
        "eval_seed": run.seed + VALIDATION_OFFSET,
        "config_file": str(run.config) if run.config else "configs/hyperparams.yml",
        "hyperparams": params,
    }
    (run_dir / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))
    command = shlex.join([sys.executable, "-m", "train", *(argv or [])])
    with open(run_dir / "command.txt", "a") as handle:
        handle.write(command + "\n")
    (run_dir / "versions.yml").write_text(yaml.safe_dump(package_versions(), sort_keys=False))
