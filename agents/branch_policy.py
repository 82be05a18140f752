"""A policy that scores every branch with one shared network (``policy: BranchPolicy``).

The default ``MlpPolicy`` reads the flat observation as one vector and must learn, for
each of the K output logits separately, which of its inputs describe that branch. Branch
choice is the same question asked K times ("how good is going to this candidate?"), so
this policy asks it once: for each branch k of the next waypoint it gathers that branch's
own slice of the observation (its normalised configuration, validity, endpoint collision,
travel and path collision from where the arm stands, and what it leads to: with the
compact observation its least travel onwards, along checked free paths over one move
and, where the env shows it, several; with the ladder observation and lookahead ≥
1 its travel to every candidate of the waypoint after, and that waypoint's validity and
endpoint flags), appends the shared context (the current configuration and progress, and
with the compact observation an order-free summary of each later slot: the share of
valid branches, the least travel into one, the share of those that are free), and maps it
through one MLP to a hidden vector h_k. The logit of branch k is a linear read-out of h_k; the value
function sees the mean of the h_k (and so does not depend on the order of the branches).
The actor is thus equivariant to the order of the branches.

Nothing here is specific to the algorithm: :class:`BranchPolicy` serves PPO and
:class:`MaskableBranchPolicy` MaskablePPO; :func:`branch_policy_kwargs` builds the
``policy_kwargs`` from an env's ``observation_layout``. The classes live in ``agents`` so
that loading a saved model needs no training code.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
import torch
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, MlpExtractor
from stable_baselines3.common.type_aliases import Schedule
from torch import nn

from .base import unwrap


class BranchFeatures(BaseFeaturesExtractor):
    """Per-branch scores (K) followed by the pooled branch embedding (``hidden``)."""

    # Buffers (``register_buffer`` below): observation columns of each branch, and shared.
    own: torch.Tensor
    shared: torch.Tensor

    def __init__(
        self,
        observation_space: gym.spaces.Box,
        layout: dict[str, list[int]],
        n_branches: int,
        dof: int,
        hidden: int = 64,
    ) -> None:
        super().__init__(observation_space, features_dim=n_branches + hidden)
        self.k, self.dof = n_branches, dof
        index = {name: torch.arange(start, stop) for name, (start, stop) in layout.items()}
        k = n_branches
        # (K, per-branch columns): which observation entries describe branch k.
        own = [
            index["slot0/candidates"].view(k, dof),
            index["slot0/valid"].view(k, 1),
            index["slot0/endpoint_collision"].view(k, 1),
            index["slot0/travel"].view(k, 1),
            index["slot0/path_collision"].view(k, 1),
        ]
        shared = [index["q"], index["progress"]]
        #: Compact observations (O(K)): each branch's least travel onwards, and per later
        #: slot a pooled summary (below) instead of its K × K travel block.
        self.compact = "slot0/travel_out" in index
        self.later = 0  # later slots summarised (compact observations)
        if self.compact:
            own.append(index["slot0/travel_out"].view(k, 1))
            for name in ("slot0/free_travel_out", "slot0/free_travel_onward"):
                if name in index:
                    own.append(index[name].view(k, 1))
            h = 1
            while f"slot{h}/present" in index:
                shared.append(index[f"slot{h}/present"])
                self.register_buffer(f"slot{h}_valid", index[f"slot{h}/valid"],
                                     persistent=False)
                self.register_buffer(f"slot{h}_in", index[f"slot{h}/travel_in"],
                                     persistent=False)
                self.register_buffer(f"slot{h}_hit", index[f"slot{h}/endpoint_collision"],
                                     persistent=False)
                h += 1
            self.later = h - 1
        elif "slot1/travel" in index:
            own.append(index["slot1/travel"].view(k, k))  # row k: from branch k onwards
            shared += [index["slot1/present"], index["slot1/valid"],
                       index["slot1/endpoint_collision"]]
        self.register_buffer("own", torch.cat(own, dim=1), persistent=False)
        self.register_buffer("shared", torch.cat(shared), persistent=False)
        width = self.own.shape[1] + len(self.shared) + (3 * self.later if self.compact else 0)
        self.embed = nn.Sequential(
            nn.Linear(width, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh()
        )
        self.score = nn.Linear(hidden, 1)

    def _slot_summaries(self, observations: torch.Tensor) -> list[torch.Tensor]:
        """Per later slot, order-free: the share of valid branches, the least travel into
        a valid one, and the share of valid ones whose configuration is free."""
        summaries = []
        for h in range(1, self.later + 1):
            valid = observations[:, getattr(self, f"slot{h}_valid")]
            travel_in = observations[:, getattr(self, f"slot{h}_in")]
            free = (1.0 - observations[:, getattr(self, f"slot{h}_hit")]) * valid
            count = valid.sum(dim=1, keepdim=True)
            least = torch.where(valid > 0, travel_in, torch.ones_like(travel_in)).amin(
                dim=1, keepdim=True)
            summaries += [count / self.k, least, free.sum(dim=1, keepdim=True) / count.clamp(
                min=1.0)]
        return summaries

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        per_branch = observations[:, self.own]  # (B, K, own)
        context = observations[:, self.shared]
        if self.compact and self.later:
            context = torch.cat([context, *self._slot_summaries(observations)], dim=1)
        context = context.unsqueeze(1).expand(-1, self.k, -1)
        embedded = self.embed(torch.cat([per_branch, context], dim=-1))  # (B, K, hidden)
        return torch.cat([self.score(embedded).squeeze(-1), embedded.mean(dim=1)], dim=-1)


class _FirstColumns(nn.Module):
    """The action logits are the extractor's first K outputs, unchanged."""

    def __init__(self, count: int | np.integer) -> None:
        super().__init__()
        self.count = count

    def forward(self, latent: torch.Tensor) -> torch.Tensor:
        return latent[:, : self.count]


class _ActorCritic(Protocol):
    """What ``_BranchScores`` uses of the SB3 policy it is mixed into (``ActorCriticPolicy``
    and ``MaskableActorCriticPolicy`` both have it), over IKBranchEnv's ``Discrete(K)``."""

    features_extractor: BaseFeaturesExtractor
    mlp_extractor: MlpExtractor
    action_space: gym.spaces.Discrete
    action_net: nn.Module
    ortho_init: bool
    optimizer_class: type[torch.optim.Optimizer]
    optimizer_kwargs: dict[str, Any]
    optimizer: torch.optim.Optimizer

    def parameters(self, recurse: bool = True) -> Iterator[nn.Parameter]: ...


class _BranchScores:
    """Replaces the action head by the branch scores (the actor's ``net_arch`` is empty)."""

    action_net: nn.Module  # the host policy's attribute, which ``_build`` replaces

    def _build(self: _ActorCritic, lr_schedule: Schedule) -> None:
        # A mixin: ``super()`` is the SB3 policy class it is mixed into (see ``_ActorCritic``),
        # which mypy cannot see from ``_BranchScores``'s own bases (only ``object``).
        super()._build(lr_schedule)  # type: ignore[misc]
        if not isinstance(self.features_extractor, BranchFeatures):
            raise ValueError("BranchPolicy needs features_extractor_class=BranchFeatures")
        if self.mlp_extractor.latent_dim_pi != self.features_extractor.features_dim:
            raise ValueError("BranchPolicy needs an empty actor net_arch (pi=[])")
        self.action_net = _FirstColumns(self.action_space.n)
        if self.ortho_init:
            # The scores are the action logits: initialise their read-out as SB3 does an
            # action head (orthogonal, gain 0.01), not with the extractor's gain √2, so
            # the initial policy is near uniform over the valid branches and explores.
            score = self.features_extractor.score
            nn.init.orthogonal_(score.weight, gain=0.01)
            nn.init.zeros_(score.bias)
        # The optimiser was built over the replaced head's parameters: build it again.
        # SB3 types the class as type[Optimizer], whose own __init__ takes no ``lr``; every
        # optimiser it is given (Adam by default) does. SB3's own ``_build`` ignores it too.
        self.optimizer = self.optimizer_class(  # type: ignore[call-arg]
            self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs
        )


class BranchPolicy(_BranchScores, ActorCriticPolicy):
    """PPO's actor-critic with shared per-branch scoring."""

    #: Read by ``agents.sb3.model_class`` from the saved zip (no unpickling needed).
    action_masks = False


class MaskableBranchPolicy(_BranchScores, MaskableActorCriticPolicy):
    """MaskablePPO's actor-critic with shared per-branch scoring."""

    action_masks = True


def branch_policy_kwargs(env: gym.Env, hidden: int = 64, **overrides: Any) -> dict[str, Any]:
    """``policy_kwargs`` for either class on ``env`` (an IKBranchEnv, possibly wrapped)."""
    base = unwrap(env)
    layout = {name: [int(a), int(b)] for name, (a, b) in base.observation_layout.items()}
    kwargs: dict[str, Any] = {
        "features_extractor_class": BranchFeatures,
        "features_extractor_kwargs": {
            "layout": layout, "n_branches": base.arm.n_branches, "dof": base.arm.dof,
            "hidden": hidden,
        },
        "net_arch": {"pi": [], "vf": [64, 64]},
    }
    kwargs.update(overrides)
    return kwargs
