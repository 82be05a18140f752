"""Policies that choose a branch per waypoint: analytic baselines and trained SB3 models.

Every policy has SB3's ``predict(obs, state=None, episode_start=None, deterministic=True,
action_masks=None) -> (action, state)``, so one loop evaluates them all; trained models
are wrapped by ``agents.sb3.SB3Policy`` (imported on demand: it pulls in torch).

================== =====================================================================
name               policy
================== =====================================================================
``paper_rule``     least travel to the next waypoint (Klyuiko 1986, per transition)
``paper_pair_rule`` least travel over the next two waypoints (the paper's K×K pairs)
``dp_oracle``      the episode's optimum: DP over the ladder graph with the env's prices
``receding_dp``    the same DP over the next ``horizon`` waypoints (default lookahead + 1)
``random``         uniform over the valid branches (``seed``)
``fixed``          one branch (``branch``: index or label), else the nearest valid one
================== =====================================================================

``agents.evaluation.evaluate`` plays any of them, an SB3 model object or any callable
``policy(obs, mask) -> action`` on the same held-out tasks beside the DP oracle, in an env
made from an id or a factory and wrapped as the policy was trained (its docstring).

``agents.branch_policy`` holds the SB3 policy classes that score every branch with one
shared network (``policy: BranchPolicy`` in ``configs/``); like ``agents.sb3`` it is
imported on demand. ``agents.exported`` decides with a trained model's actor exported to
an ``.npz`` (``ikbranch export``), with numpy alone.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from .base import Baseline, Policy
from .dp import DPOracle, RecedingDP, ladder_q_tables
from .rules import FixedBranch, PaperPairRule, PaperRule, RandomBranch

BASELINES: dict[str, type[Baseline]] = {
    cls.name: cls
    for cls in (PaperRule, PaperPairRule, DPOracle, RecedingDP, RandomBranch, FixedBranch)
}


def make_baseline(name: str, env: gym.Env, **kwargs: Any) -> Baseline:
    """The baseline ``name`` bound to ``env`` (it reads the task from it).

    Keyword arguments go to the baseline: ``seed`` (random), ``branch`` (fixed),
    ``horizon`` (receding_dp). ``ValueError`` for an unknown name.
    """
    if name not in BASELINES:
        raise ValueError(f"unknown baseline {name!r}; choose one of {', '.join(BASELINES)}")
    return BASELINES[name](env, **kwargs)


__all__ = [
    "BASELINES",
    "Baseline",
    "DPOracle",
    "FixedBranch",
    "PaperPairRule",
    "PaperRule",
    "Policy",
    "RandomBranch",
    "RecedingDP",
    "ladder_q_tables",
    "make_baseline",
]
