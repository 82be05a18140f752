"""Hyper-parameters: ``configs/hyperparams.yml`` keyed by env id, as in rl-baselines3-zoo.

One block per env id serves every algorithm; a key named after an algorithm holds that
algorithm's overrides. Unlike the zoo there is no ``default`` entry: asking for an id the
file does not list is an error, so a typo never trains with silently wrong settings. The
key ``_anchors`` only carries YAML anchors that entries merge in by name.
"""

from __future__ import annotations

import importlib
import importlib.resources
from pathlib import Path
from typing import Any

import yaml

#: The hyper-parameters that ship with the package (``configs/`` of a checkout, package
#: data of an installed wheel).
CONFIG = Path(str(importlib.resources.files("ikbranch_gym.configs") / "hyperparams.yml"))
#: The algorithms: name -> "module:class" (imported only when a run needs it).
#: ``bc_maskable_ppo`` is MaskablePPO started from behaviour cloning of the DP oracle
#: (``train.imitation``).
ALGORITHMS = {"ppo": "stable_baselines3:PPO", "maskable_ppo": "sb3_contrib:MaskablePPO",
              "bc_maskable_ppo": "sb3_contrib:MaskablePPO"}
#: The algorithms that clone the oracle before PPO, and the keys of their imitation phase.
IMITATION_ALGORITHMS = ("bc_maskable_ppo",)
IMITATION_KEYS = ("imitation_episodes", "imitation_epochs", "imitation_batch_size",
                  "imitation_learning_rate")
#: Keys of an entry that are not constructor arguments of the algorithm.
RUN_KEYS = ("n_timesteps", "n_envs", "policy", "eval_freq", "n_eval_episodes",
            "checkpoint_freq", "env_kwargs", "normalize_reward", *IMITATION_KEYS)
ANCHORS = "_anchors"


def check_algorithm(algo: str) -> str:
    if algo not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGORITHMS)}")
    return algo


def uses_masks(algo: str) -> bool:
    """Whether ``algo`` trains a masked policy (sb3-contrib's MaskablePPO)."""
    return ALGORITHMS[check_algorithm(algo)].endswith(":MaskablePPO")


def algorithm_class(algo: str) -> type:
    """The SB3 class of ``algo``."""
    module, _, name = ALGORITHMS[check_algorithm(algo)].partition(":")
    return getattr(importlib.import_module(module), name)


def load_config(path: str | Path = CONFIG) -> dict[str, dict[str, Any]]:
    """The whole file: env id -> entry. ``ValueError`` for a key that is no registered id,
    or an override block for an unknown algorithm."""
    import ikbranch_gym.envs as envs

    with open(path) as handle:
        config = yaml.safe_load(handle) or {}
    if not isinstance(config, dict):
        raise ValueError(f"{path}: expected a mapping of env ids to hyper-parameters")
    config.pop(ANCHORS, None)
    unknown = sorted(set(config) - set(envs.ENV_IDS))
    if unknown:
        raise ValueError(f"{path}: keys are not registered env ids: {', '.join(unknown)}")
    for entry in config.values():
        for key, value in entry.items():
            if isinstance(value, dict) and key not in ("policy_kwargs", "env_kwargs"):
                check_algorithm(key)  # a nested block is an algorithm's overrides
    return config


def hyperparams_for(env_id: str, algo: str, path: str | Path | None = None) -> dict[str, Any]:
    """The entry for ``env_id`` in ``path`` (default ``configs/hyperparams.yml``) with
    ``algo``'s overrides applied, copied."""
    check_algorithm(algo)
    path = CONFIG if path is None else Path(path)
    config = load_config(path)
    if env_id not in config:
        raise ValueError(f"{path} has no entry for {env_id!r} (no silent defaults)")
    entry = {key: value for key, value in config[env_id].items() if key not in ALGORITHMS}
    entry.update(config[env_id].get(algo, {}))
    return entry
