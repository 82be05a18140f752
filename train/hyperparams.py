"""Hyper-parameters: YAML files in ``configs/`` keyed by env id, as in rl-baselines3-zoo.

Unlike the zoo there is no ``default`` entry: asking for an id a file does not list is an
error, so a typo never trains with silently wrong settings.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"
ALGOS = ("ppo", "maskable_ppo")
#: Keys of an entry that are not constructor arguments of the algorithm.
RUN_KEYS = ("n_timesteps", "n_envs", "policy", "eval_freq", "n_eval_episodes",
            "checkpoint_freq", "env_kwargs", "normalize_reward")


def config_path(algo: str) -> Path:
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGOS)}")
    return CONFIG_DIR / f"{algo}.yml"


def load_config(path: str | Path) -> dict[str, dict[str, Any]]:
    """The whole file: env id -> entry. ``ValueError`` for a key that is no registered id."""
    import envs

    with open(path) as handle:
        config = yaml.safe_load(handle) or {}
    if not isinstance(config, dict):
        raise ValueError(f"{path}: expected a mapping of env ids to hyper-parameters")
    unknown = sorted(set(config) - set(envs.ENV_IDS))
    if unknown:
        raise ValueError(f"{path}: keys are not registered env ids: {', '.join(unknown)}")
    return config


def hyperparams_for(env_id: str, algo: str, path: str | Path | None = None) -> dict[str, Any]:
    """The entry for ``env_id`` in ``path`` (default ``configs/<algo>.yml``), copied."""
    path = config_path(algo) if path is None else Path(path)
    config = load_config(path)
    if env_id not in config:
        raise ValueError(f"{path} has no entry for {env_id!r} (no silent defaults)")
    return dict(config[env_id])
