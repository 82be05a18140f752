"""Behaviour cloning from the DP oracle before PPO: the ``bc_maskable_ppo`` algorithm.

The oracle (``agents.DPOracle``, the global optimum of each episode) plays
``imitation_episodes`` training tasks; the policy is then fitted to its choices by
minimising the cross-entropy of the masked branch distribution (and its value head to the
discounted returns, in the reward scale PPO will train on), and MaskablePPO continues from
there. The pure PPO and MaskablePPO rows stay beside it in the results, so a reader sees
what the oracle's help buys; the oracle's episodes are counted apart from PPO's steps
(``imitation.json`` in the run directory).

The demonstrations play task seeds ``run seed + IMITATION_OFFSET + e`` (``envs.seeds``)
on the run's own (training) scenes: never a held-out task or scene. Minibatches are drawn
from a generator seeded by the run's seed, so a run is reproducible.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from sb3_contrib import MaskablePPO
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.vec_env import VecNormalize

from ikbranch_gym.agents import DPOracle
from ikbranch_gym.agents.base import action_mask
from ikbranch_gym.envs.seeds import IMITATION_OFFSET
from ikbranch_gym.train.hyperparams import IMITATION_KEYS

#: Written to the run directory after cloning.
RECORD = "imitation.json"


@dataclass(frozen=True)
class Demonstrations:
    """The oracle's decisions, one row per step: what the policy saw (observation and
    action mask), what the oracle chose, the reward and whether the step ended the
    episode."""

    observations: np.ndarray
    masks: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    ends: np.ndarray
    episodes: int

    def __len__(self) -> int:
        return len(self.actions)


def oracle_demonstrations(env: gym.Env, episodes: int, seed: int) -> Demonstrations:
    """``episodes`` episodes of ``DPOracle`` on ``env``, task seeds ``seed + e``."""
    if episodes < 1:
        raise ValueError(f"imitation_episodes must be at least 1, got {episodes}")
    oracle = DPOracle(env)
    rows: dict[str, list] = {"observations": [], "masks": [], "actions": [], "rewards": [],
                             "ends": []}
    for e in range(episodes):
        observation, info = env.reset(seed=seed + e)
        done = False
        while not done:
            mask = action_mask(env, info)
            action, _ = oracle.predict(observation, action_masks=mask)
            rows["observations"].append(observation)
            rows["masks"].append(mask)
            rows["actions"].append(int(action))
            observation, reward, terminated, truncated, info = env.step(int(action))
            done = bool(terminated or truncated)
            rows["rewards"].append(float(reward))
            rows["ends"].append(done)
    return Demonstrations(
        observations=np.asarray(rows["observations"], dtype=np.float32),
        masks=np.asarray(rows["masks"], dtype=bool),
        actions=np.asarray(rows["actions"], dtype=np.int64),
        rewards=np.asarray(rows["rewards"], dtype=np.float64),
        ends=np.asarray(rows["ends"], dtype=bool),
        episodes=episodes,
    )


def discounted_returns(rewards: np.ndarray, ends: np.ndarray, gamma: float) -> np.ndarray:
    """Per step, Σ_i γ^i r_{t+i} to the end of its episode."""
    out = np.empty_like(rewards)
    running = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        if ends[t]:
            running = 0.0
        running = rewards[t] + gamma * running
        out[t] = running
    return out


def seed_reward_scale(stats: RunningMeanStd, demos: Demonstrations, gamma: float) -> None:
    """Feed the demonstrations' rewards to ``VecNormalize``'s return statistics exactly as
    its own steps would (a running discounted sum, reset at each episode's end), so PPO's
    first rewards are scaled as the value head was fitted."""
    running = 0.0
    for reward, end in zip(demos.rewards, demos.ends, strict=True):
        running = running * gamma + reward
        stats.update(np.array([running]))
        if end:
            running = 0.0


def clone(model: MaskablePPO, demos: Demonstrations, *, epochs: int, batch_size: int,
          learning_rate: float, gamma: float, reward_scale: float, seed: int) -> dict[str, Any]:
    """Fit ``model``'s policy to the demonstrations: the masked cross-entropy of the
    oracle's choices plus ``vf_coef`` × the squared error of the value head against the
    discounted returns over ``reward_scale``. Returns the final epoch's mean losses and the
    share of demonstrated decisions the fitted policy takes (deterministically)."""
    for key, value in (("imitation_epochs", epochs), ("imitation_batch_size", batch_size)):
        if not isinstance(value, int) or value < 1:
            raise ValueError(f"{key} must be a positive integer, got {value!r}")
    if not learning_rate > 0.0:
        raise ValueError(f"imitation_learning_rate must be positive, got {learning_rate!r}")
    policy = model.policy
    device = policy.device
    observations = torch.as_tensor(demos.observations, device=device)
    masks = torch.as_tensor(demos.masks, device=device)
    actions = torch.as_tensor(demos.actions, device=device)
    targets = torch.as_tensor(
        discounted_returns(demos.rewards, demos.ends, gamma) / reward_scale,
        dtype=torch.float32, device=device)
    optimizer = torch.optim.Adam(policy.parameters(), lr=learning_rate)
    generator = torch.Generator().manual_seed(seed)
    policy.set_training_mode(True)
    last: dict[str, float] = {}
    for _ in range(epochs):
        order = torch.randperm(len(actions), generator=generator).to(device)
        totals = {"action_loss": 0.0, "value_loss": 0.0}
        for start in range(0, len(order), batch_size):
            batch = order[start : start + batch_size]
            values, log_prob, _ = policy.evaluate_actions(observations[batch], actions[batch],
                                                          action_masks=masks[batch])
            action_loss = -log_prob.mean()
            value_loss = torch.nn.functional.mse_loss(values.flatten(), targets[batch])
            loss = action_loss + model.vf_coef * value_loss
            optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), model.max_grad_norm)
            optimizer.step()
            totals["action_loss"] += action_loss.item() * len(batch)
            totals["value_loss"] += value_loss.item() * len(batch)
        last = {key: value / len(order) for key, value in totals.items()}
    policy.set_training_mode(False)
    with torch.no_grad():
        chosen, _, _ = policy(observations, deterministic=True, action_masks=masks)
    last["agreement"] = float((chosen == actions).float().mean())
    return last


def warm_start(model: MaskablePPO, env: gym.Env, params: dict[str, Any], seed: int,
               normalizer: VecNormalize | None, run_dir: Path) -> dict[str, Any]:
    """The imitation phase of a run: demonstrations on ``env`` (a single env of the run's
    id and kwargs), the return statistics of ``normalizer`` (the training env's
    ``VecNormalize``, None without reward normalisation) seeded from them, the policy
    cloned; the record is written to ``run_dir / RECORD`` and returned."""
    missing = [key for key in IMITATION_KEYS if key not in params]
    if missing:
        raise ValueError(f"bc_maskable_ppo needs {', '.join(missing)} in its hyper-parameters")
    demos = oracle_demonstrations(env, int(params["imitation_episodes"]),
                                  seed + IMITATION_OFFSET)
    scale = 1.0
    if normalizer is not None:
        seed_reward_scale(normalizer.ret_rms, demos, normalizer.gamma)
        # The divisor VecNormalize.normalize_reward applies.
        scale = float(np.sqrt(normalizer.ret_rms.var + normalizer.epsilon))
    fitted = clone(model, demos, epochs=params["imitation_epochs"],
                   batch_size=params["imitation_batch_size"],
                   learning_rate=float(params["imitation_learning_rate"]), gamma=model.gamma,
                   reward_scale=scale, seed=seed)
    record = {"episodes": demos.episodes, "steps": len(demos),
              "task_seeds": [seed + IMITATION_OFFSET, seed + IMITATION_OFFSET + demos.episodes],
              "oracle_mean_return": float(demos.rewards.sum() / demos.episodes),
              "reward_scale": scale, **fitted}
    (run_dir / RECORD).write_text(json.dumps(record, indent=2) + "\n")
    return record
