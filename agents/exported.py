"""A trained policy as a controller runs it: the actor alone, in numpy, from one ``.npz``.

A deployed branch chooser needs the decision and nothing else: no value head, no
distribution objects, no torch. :func:`export_policy` writes the actor of a PPO or
MaskablePPO model (``BranchPolicy`` or SB3's ``MlpPolicy``) to an ``.npz`` of plain arrays
(no pickles); :class:`ExportedPolicy` loads it with numpy alone and decides:

- ``BranchPolicy``: per branch k its own observation columns and the shared context (with
  the compact observation, each later slot's share of valid branches, least travel into
  one and share of free ones), through the shared two-layer tanh MLP to the score of k;
- ``MlpPolicy``: the observation through the actor's layers to the K logits;

then the highest logit, among the branches the mask allows for a model trained with
masks (MaskablePPO), among all for one trained without (PPO): SB3's deterministic action.

The arithmetic is float32, as torch's, but in another order (per-branch and shared
columns through two products where torch concatenates first), so logits agree to float32
rounding (~1e-6), not bit for bit; a decision could differ only between two branches
whose logits are that close. ``ikbranch export`` checks the decisions against the model's
own on held-out episodes before it writes the file.

numpy's matrix products may use several BLAS threads; on a busy machine a controller runs
faster with one (``OPENBLAS_NUM_THREADS=1`` before numpy is imported).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import gymnasium as gym
    from stable_baselines3.common.base_class import BaseAlgorithm

#: The ``format`` entry of an exported policy's file, and the layout version it holds.
FORMAT, VERSION = "ikbranch-exported-policy", 1
#: The actors' activations by the name of their torch module.
ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "Tanh": np.tanh, "ReLU": lambda x: np.maximum(x, np.float32(0.0))}


class ExportedPolicy:
    """The actor of a trained model as plain arrays (``arrays``: an exported file's
    entries); SB3's ``predict`` for evaluation, :meth:`decide` for a controller."""

    def __init__(self, arrays: dict[str, np.ndarray], name: str = "exported",
                 env: gym.Env | None = None) -> None:
        self.name, self.env = name, env
        self.kind = str(arrays["kind"])
        self.maskable = bool(arrays["masked"])
        self.observation_size = int(arrays["observation_size"])
        self.n_branches = int(arrays["n_branches"])
        if self.kind == "branch":
            self._own, self._shared = arrays["own"], arrays["shared"]
            self._slots = arrays["slot_valid"], arrays["slot_in"], arrays["slot_hit"]
            width = self._own.shape[1]
            first = arrays["embed0_weight"]
            # Torch applies the first layer to [own columns, context]: split its weight.
            self._first_own = np.ascontiguousarray(first[:, :width].T)
            self._first_context = np.ascontiguousarray(first[:, width:].T)
            self._first_bias = arrays["embed0_bias"]
            self._second = np.ascontiguousarray(arrays["embed1_weight"].T)
            self._second_bias = arrays["embed1_bias"]
            self._score = np.ascontiguousarray(arrays["score_weight"][0])
            self._score_bias = arrays["score_bias"][0]
        else:
            layers = int(arrays["layers"])
            self._layers = [(np.ascontiguousarray(arrays[f"layer{i}_weight"].T),
                             arrays[f"layer{i}_bias"]) for i in range(layers)]
            self._activation = ACTIVATIONS[str(arrays["activation"])]
            self._action = (np.ascontiguousarray(arrays["action_weight"].T),
                            arrays["action_bias"])
        if env is not None and env.observation_space.shape != (self.observation_size,):
            raise ValueError(f"{name}: exported for observations of size "
                             f"{self.observation_size}, the env gives "
                             f"{env.observation_space.shape}")

    # ------------------------------------------------------------------------ files
    @classmethod
    def load(cls, path: str | Path, env: gym.Env | None = None) -> ExportedPolicy:
        """Read an exported policy (``ValueError`` naming the file for anything that is not
        one), checked against ``env``'s observations where given."""
        try:
            with np.load(path, allow_pickle=False) as stored:
                arrays = {key: stored[key] for key in stored.files}
        except (OSError, ValueError) as error:
            raise ValueError(f"{path}: not an exported policy ({error})") from error
        if arrays.get("format") is None or str(arrays["format"]) != FORMAT:
            raise ValueError(f"{path}: not an exported policy (no format {FORMAT!r})")
        version = arrays.get("version")
        if version is None or int(version) != VERSION:
            raise ValueError(f"{path}: exported policy version "
                             f"{'missing' if version is None else int(version)}; this "
                             f"package reads version {VERSION}")
        missing = sorted(set(_required(str(arrays.get("kind")), arrays)) - set(arrays))
        if missing:
            raise ValueError(f"{path}: exported policy without {', '.join(missing)}")
        if str(arrays["kind"]) == "mlp" and str(arrays["activation"]) not in ACTIVATIONS:
            raise ValueError(f"{path}: activation {str(arrays['activation'])!r}; this package "
                             f"reads {', '.join(ACTIVATIONS)}")
        return cls(arrays, name=Path(path).stem, env=env)

    # -------------------------------------------------------------------- decisions
    def logits(self, observations: np.ndarray) -> np.ndarray:
        """(B, K) float32 logits of observations (B, size)."""
        x = self._observations(observations)
        if self.kind == "mlp":
            for weight, bias in self._layers:
                x = self._activation(x @ weight + bias)
            weight, bias = self._action
            return x @ weight + bias
        context = [x[:, self._shared]]
        k = np.float32(self.n_branches)
        for valid_columns, in_columns, hit_columns in zip(*self._slots, strict=True):
            valid = x[:, valid_columns]
            count = valid.sum(axis=1, keepdims=True)
            least = np.where(valid > 0, x[:, in_columns], np.float32(1.0)).min(
                axis=1, keepdims=True)
            free = ((np.float32(1.0) - x[:, hit_columns]) * valid).sum(axis=1, keepdims=True)
            context += [count / k, least, free / np.maximum(count, np.float32(1.0))]
        shared = np.concatenate(context, axis=1) @ self._first_context + self._first_bias
        hidden = np.tanh(x[:, self._own] @ self._first_own + shared[:, None, :])
        hidden = np.tanh(hidden @ self._second + self._second_bias)
        return hidden @ self._score + self._score_bias

    def decide_many(self, observations: np.ndarray,
                    masks: np.ndarray | None = None) -> np.ndarray:
        """(B,) the branch of each of observations (B, size): the highest logit, among the
        branches of ``masks`` (B, K) for a model trained with masks."""
        logits = self.logits(observations)
        if self.maskable:
            if masks is None:
                raise ValueError(f"{self.name} was trained with action masks: pass them")
            masks = np.asarray(masks, dtype=bool).reshape(len(logits), -1)
            if masks.shape != logits.shape:
                raise ValueError(f"masks of shape {masks.shape} for {len(logits)} "
                                 f"observations of {self.n_branches} branches")
            if not masks.any(axis=1).all():
                raise ValueError(f"a mask without a valid branch (rows "
                                 f"{np.flatnonzero(~masks.any(axis=1)).tolist()})")
            logits = np.where(masks, logits, -np.inf)
        return logits.argmax(axis=1)

    def decide(self, observation: np.ndarray, mask: np.ndarray | None = None) -> int:
        """The branch for one observation (size,), ``mask`` (K,) as in :meth:`decide_many`."""
        return int(self.decide_many(observation[None], None if mask is None else mask[None])[0])

    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None, deterministic: bool = True,
                action_masks: np.ndarray | None = None) -> tuple[np.ndarray, Any]:
        """SB3's ``predict`` (the evaluation loop's interface): deterministic only."""
        if not deterministic:
            raise ValueError("an exported policy decides deterministically")
        if self.maskable and action_masks is None and self.env is not None:
            from .base import action_mask

            action_masks = action_mask(self.env)
        one = np.ndim(observation) == 1
        actions = self.decide_many(np.atleast_2d(observation),
                                   action_masks if self.maskable else None)
        return (actions[0] if one else actions), state

    def _observations(self, observations: np.ndarray) -> np.ndarray:
        x = np.asarray(observations)
        if x.ndim != 2 or x.shape[1] != self.observation_size:
            raise ValueError(f"observations of shape {x.shape}; {self.name} takes (B, "
                             f"{self.observation_size})")
        if not np.isfinite(x).all():
            raise ValueError("observations with NaN or infinite entries")
        return x.astype(np.float32, copy=False)


def _required(kind: str, arrays: dict[str, np.ndarray]) -> list[str]:
    """The entries an exported policy of ``kind`` must hold."""
    common = ["kind", "masked", "observation_size", "n_branches"]
    if kind == "branch":
        return [*common, "own", "shared", "slot_valid", "slot_in", "slot_hit",
                "embed0_weight", "embed0_bias", "embed1_weight", "embed1_bias",
                "score_weight", "score_bias"]
    if kind == "mlp":
        layers = int(arrays["layers"]) if "layers" in arrays else 0
        return [*common, "layers", "activation", "action_weight", "action_bias",
                *(f"layer{i}_{part}" for i in range(layers) for part in ("weight", "bias"))]
    return [*common, "kind (branch or mlp)"]


# ------------------------------------------------------------------------------ export
def exported_arrays(model: BaseAlgorithm) -> dict[str, np.ndarray]:
    """The arrays of a PPO or MaskablePPO model's actor (``BranchPolicy`` or ``MlpPolicy``),
    as :class:`ExportedPolicy` reads them; ``ValueError`` for another architecture."""
    from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy
    from stable_baselines3.common.torch_layers import FlattenExtractor
    from torch import nn

    from .branch_policy import BranchFeatures

    policy: Any = model.policy  # SB3 types its modules as Tensor | Module

    def array(tensor: Any) -> np.ndarray:
        return tensor.detach().cpu().numpy().astype(np.float32)

    shape = model.observation_space.shape
    if shape is None or len(shape) != 1:
        raise ValueError(f"flat observations only, got shape {shape}")
    out: dict[str, np.ndarray] = {
        "format": np.array(FORMAT), "version": np.array(VERSION),
        "masked": np.array(isinstance(policy, MaskableActorCriticPolicy)),
        "observation_size": np.array(shape[0]),
        "n_branches": np.array(int(model.action_space.n)),  # type: ignore[attr-defined]
    }
    extractor = policy.features_extractor
    if isinstance(extractor, BranchFeatures):
        # Later slots are summarised (``later`` > 0) with the compact observation only.
        slots = [[getattr(extractor, f"slot{h}_{part}").numpy()
                  for h in range(1, extractor.later + 1)]
                 for part in ("valid", "in", "hit")]
        k = extractor.k
        out.update(
            kind=np.array("branch"), own=extractor.own.numpy(), shared=extractor.shared.numpy(),
            **{f"slot_{part}": (np.array(rows, dtype=np.int64) if rows else
                                np.zeros((0, k), dtype=np.int64))
               for part, rows in zip(("valid", "in", "hit"), slots, strict=True)},
            embed0_weight=array(extractor.embed[0].weight),
            embed0_bias=array(extractor.embed[0].bias),
            embed1_weight=array(extractor.embed[2].weight),
            embed1_bias=array(extractor.embed[2].bias),
            score_weight=array(extractor.score.weight), score_bias=array(extractor.score.bias))
        return out
    if not isinstance(extractor, FlattenExtractor):
        raise ValueError(f"cannot export a {type(extractor).__name__} feature extractor "
                         "(BranchFeatures or SB3's FlattenExtractor)")
    layers = [module for module in policy.mlp_extractor.policy_net]
    linear = [module for module in layers if isinstance(module, nn.Linear)]
    activations = {type(module).__name__ for module in layers
                   if not isinstance(module, nn.Linear)}
    if not activations <= set(ACTIVATIONS) or len(activations) > 1:
        raise ValueError(f"cannot export activations {sorted(activations)} "
                         f"({', '.join(ACTIVATIONS)})")
    out.update(kind=np.array("mlp"), layers=np.array(len(linear)),
               activation=np.array(activations.pop() if activations else "Tanh"),
               action_weight=array(policy.action_net.weight),
               action_bias=array(policy.action_net.bias))
    for i, module in enumerate(linear):
        out[f"layer{i}_weight"], out[f"layer{i}_bias"] = array(module.weight), array(module.bias)
    return out


def export_policy(model: BaseAlgorithm, path: str | Path) -> Path:
    """Write ``model``'s actor to ``path`` (an ``.npz``); returns the path."""
    return write_exported(exported_arrays(model), path)


def write_exported(arrays: dict[str, np.ndarray], path: str | Path) -> Path:
    """Write the arrays of an exported actor (:func:`exported_arrays`) to ``path``, an
    ``.npz`` (``ValueError`` for another suffix); returns the path."""
    path = Path(path)
    if path.suffix != ".npz":
        raise ValueError(f"{path}: an exported policy is written as a .npz file")
    entries: dict[str, Any] = arrays
    np.savez(path, **entries)
    return path
