"""Trained SB3 models behind the same ``predict`` as the baselines.

A zip saved by ``PPO.save`` or ``MaskablePPO.save`` is recognised from its ``data`` record
(the module of its policy class) without unpickling anything, then loaded by the right
class; a MaskablePPO model is always given the env's action masks.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from sb3_contrib import MaskablePPO
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy
from stable_baselines3 import PPO
from stable_baselines3.common.base_class import BaseAlgorithm

from .base import action_mask


def model_class(path: str | Path) -> type[BaseAlgorithm]:
    """PPO or MaskablePPO, from the policy class recorded in the zip."""
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
    except (OSError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: not an SB3 model zip ({error})") from error
    policy = data.get("policy_class", {})
    module = str(policy.get("__module__", ""))
    # Our own policy classes (ikbranch_gym.agents.branch_policy) say whether they mask.
    masks = policy.get("action_masks")
    if "maskable" in module or masks is True:
        return MaskablePPO
    if (module.startswith("stable_baselines3") or masks is False) and "clip_range" in data:
        return PPO
    raise ValueError(f"{path}: a {module or 'unknown'} policy; expected PPO or MaskablePPO")


#: Modules that models saved before the package was named ``ikbranch_gym`` name by their
#: old import names (their pickled policy class and feature extractor).
FORMER_NAMES = ("agents", "agents.branch_policy")


@contextlib.contextmanager
def former_module_names() -> Iterator[None]:
    """While loading a model, :data:`FORMER_NAMES` resolve to this package's modules, so a
    model that pickled ``agents.branch_policy.BranchPolicy`` loads; whatever those names
    meant before (a user's own ``agents`` package, or nothing) is restored afterwards."""
    saved = {name: sys.modules.get(name) for name in FORMER_NAMES}
    for name in FORMER_NAMES:
        sys.modules[name] = importlib.import_module(f"ikbranch_gym.{name}")
    try:
        yield
    finally:
        for name, module in saved.items():
            if module is None:
                del sys.modules[name]
            else:
                sys.modules[name] = module


def load_model(algorithm: type[BaseAlgorithm], path: str | Path, **kwargs: Any) -> BaseAlgorithm:
    """``algorithm.load(path, **kwargs)``, for models saved under either import name."""
    with former_module_names():
        return algorithm.load(path, **kwargs)


class SB3Policy:
    """An SB3 model with the baselines' ``predict``; masks reach MaskablePPO only.

    Any SB3 algorithm works (PPO, MaskablePPO, A2C, DQN, …: whatever has ``predict``); a
    model whose policy can mask (MaskablePPO's) is given the masks the caller passes, else
    those of ``env``'s outermost wrapper (``agents.base.action_mask``).
    """

    def __init__(self, model: BaseAlgorithm, env: gym.Env | None = None, name: str = "") -> None:
        self.model = model
        self.env = env
        self.name = name
        self.maskable = isinstance(model.policy, MaskableActorCriticPolicy)

    @classmethod
    def wrap(cls, model: BaseAlgorithm, env: gym.Env | None = None, name: str = "") -> SB3Policy:
        """An SB3 model object, checked against ``env``'s observations (wrappers included)."""
        if not isinstance(model, BaseAlgorithm):
            raise TypeError(f"expected an SB3 model, got {type(model).__name__}")
        name = name or type(model).__name__
        check_observations(model, env, name)
        return cls(model, env, name=name)

    @classmethod
    def load(cls, path: str | Path, env: gym.Env | None = None) -> SB3Policy:
        """Load ``path`` with the class it was saved from (CPU), checked against ``env``."""
        algorithm = model_class(path)
        model = load_model(algorithm, path, device="cpu")
        if algorithm is MaskablePPO and not isinstance(model.policy, MaskableActorCriticPolicy):
            raise ValueError(f"{path}: recorded as MaskablePPO but its policy cannot mask")
        check_observations(model, env, str(path))
        return cls(model, env, name=Path(path).stem)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
        action_masks: np.ndarray | None = None,
    ) -> tuple[np.ndarray, Any]:
        if not self.maskable:
            return self.model.predict(observation, state, episode_start, deterministic)
        if action_masks is None and self.env is not None:
            action_masks = action_mask(self.env)
        # A maskable policy: the model is a MaskablePPO, whose predict takes the masks.
        assert isinstance(self.model, MaskablePPO)
        return self.model.predict(
            observation, state, episode_start, deterministic, action_masks=action_masks
        )


def check_observations(model: BaseAlgorithm, env: gym.Env | None, what: str) -> None:
    """``ValueError`` unless ``model`` was trained on observations of ``env``'s shape."""
    if env is not None and model.observation_space.shape != env.observation_space.shape:
        raise ValueError(
            f"{what}: trained on observations of shape {model.observation_space.shape}, "
            f"the env gives {env.observation_space.shape} (same env id and --env-kwargs, "
            "e.g. lookahead, and the same wrappers as in training?)"
        )
