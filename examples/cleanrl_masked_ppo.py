"""Masked PPO in one file, CleanRL style: torch and the env, no RL library.

    python examples/cleanrl_masked_ppo.py --total-timesteps 20000
    python examples/cleanrl_masked_ppo.py --env-id IKBranch/ToolTransfer-v1 --total-timesteps 60000

Trains on ``gym.make_vec(ENV_ID, num_envs=N, vectorization_mode="vector_entry_point",
autoreset_mode="same_step")``: N copies of the env advanced together in this process.
Everything a masked learner needs is in each step's ``info["action_mask"]`` (N, K):

- Masking: the logits of the branches a mask forbids are set to -1e8 before the
  categorical distribution, so they get probability 0 (and add 0 to the entropy). The
  mask of every step is stored in the rollout and used again in the update: the new
  log-probabilities are taken over the same branches the action was drawn from.
- Autoreset ``same_step``: a step that ends a sub-env's episode returns the *next*
  episode's first observation and mask (the last ones are in ``info["final_obs"]`` and
  ``info["final_info"]``), so the mask in hand always belongs to the observation in hand.
  The ended episode's last value is not bootstrapped (``done`` cuts the GAE recursion);
  these envs never truncate: an episode ends by finishing, a collision or an invalid
  branch.
- Rewards are divided by a running standard deviation of the discounted return and
  clipped to ±10, as SB3's ``VecNormalize(norm_obs=False, norm_reward=True)`` does (the
  project measured PPO collapsing onto one branch without it: docs/training.md).
- GAE(λ), the clipped surrogate objective, an unclipped value loss, a constant learning
  rate (``--anneal-lr true`` decays it to 0 over the budget, as CleanRL does by default).

The default id, RodMechanism-v2, masks most branches (about 60 % of them at a step of a
random policy), so the masking does work there; on ToolTransfer-v1 every branch of every
waypoint is valid and the mask is all True. At the end the project's evaluation loop plays
the greedy policy (``Agent.act``, a callable ``(obs, mask) -> action``), the same network
before training, a uniformly random masked policy and the DP oracle on the same held-out
tasks (task seeds from ``envs.seeds.TEST_SEED``, held-out scenes where the id draws
clutter) and prints the comparison table. ``main`` returns the numbers as a dict.
"""

from __future__ import annotations

import argparse
import copy
import math
import time
from dataclasses import asdict, dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from torch import nn
from torch.distributions import Categorical

import ikbranch_gym  # noqa: F401  (registers the env ids)
from ikbranch_gym.agents.evaluation import evaluate
from ikbranch_gym.envs.seeds import TEST_SEED, held_out
from ikbranch_gym.train.evaluate import table

ENV_ID = "IKBranch/RodMechanism-v2"
#: The logit a masked branch gets (sb3-contrib's MaskablePPO uses the same value).
MASKED_LOGIT = -1e8


@dataclass
class Args:
    env_id: str = ENV_ID
    total_timesteps: int = 20_000  # env steps, summed over the sub-envs
    num_envs: int = 8
    num_steps: int = 128  # steps per sub-env per rollout
    learning_rate: float = 3e-4
    anneal_lr: bool = False
    gamma: float = 0.99
    gae_lambda: float = 0.95
    num_minibatches: int = 4
    update_epochs: int = 5
    clip_coef: float = 0.2
    ent_coef: float = 0.01
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    normalize_reward: bool = True
    seed: int = 0
    eval_episodes: int = 50
    torch_threads: int = 1
    save: str = ""  # write the trained agent's state_dict here (.pt)


def layer(in_size: int, out_size: int, gain: float = math.sqrt(2)) -> nn.Linear:
    linear = nn.Linear(in_size, out_size)
    nn.init.orthogonal_(linear.weight, gain)
    nn.init.zeros_(linear.bias)
    return linear


class Agent(nn.Module):
    """Separate actor and critic MLPs (2 × 64, tanh), CleanRL's defaults."""

    def __init__(self, obs_size: int, n_actions: int) -> None:
        super().__init__()
        self.critic = nn.Sequential(layer(obs_size, 64), nn.Tanh(), layer(64, 64), nn.Tanh(),
                                    layer(64, 1, gain=1.0))
        # A small last layer: the first policy is near uniform over the valid branches.
        self.actor = nn.Sequential(layer(obs_size, 64), nn.Tanh(), layer(64, 64), nn.Tanh(),
                                   layer(64, n_actions, gain=0.01))

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.critic(obs).squeeze(-1)

    def distribution(self, obs: torch.Tensor, mask: torch.Tensor) -> Categorical:
        logits = self.actor(obs)
        return Categorical(logits=torch.where(mask, logits, torch.full_like(logits, MASKED_LOGIT)))

    def act(self, obs: np.ndarray, mask: np.ndarray) -> int:
        """The most probable allowed branch for one observation and its (K,) mask."""
        with torch.no_grad():
            dist = self.distribution(torch.as_tensor(obs, dtype=torch.float32)[None],
                                     torch.as_tensor(mask, dtype=torch.bool)[None])
        return int(dist.probs.argmax())


class ReturnScale:
    """Rewards over the running std of the discounted return, clipped (``VecNormalize``)."""

    def __init__(self, num_envs: int, gamma: float, clip: float = 10.0) -> None:
        self.gamma, self.clip, self.returns = gamma, clip, np.zeros(num_envs)
        self.count, self.mean, self.var = 1e-4, 0.0, 1.0

    def __call__(self, rewards: np.ndarray, dones: np.ndarray) -> np.ndarray:
        self.returns = self.returns * self.gamma + rewards
        batch_mean, batch_var, n = self.returns.mean(), self.returns.var(), len(rewards)
        total = self.count + n
        delta = batch_mean - self.mean
        self.mean += delta * n / total
        self.var = (self.var * self.count + batch_var * n
                    + delta**2 * self.count * n / total) / total
        self.count = total
        self.returns[dones] = 0.0
        return np.clip(rewards / np.sqrt(self.var + 1e-8), -self.clip, self.clip)


class Rollout:
    """One rollout's tensors, (num_steps, num_envs, …)."""

    def __init__(self, t: int, n: int, obs_size: int, n_actions: int) -> None:
        self.obs = torch.zeros((t, n, obs_size))
        self.masks = torch.zeros((t, n, n_actions), dtype=torch.bool)
        self.actions = torch.zeros((t, n), dtype=torch.long)
        self.logprobs, self.rewards, self.starts, self.values = (torch.zeros((t, n))
                                                                 for _ in range(4))


def advantages(rollout: Rollout, next_value: torch.Tensor, next_done: np.ndarray,
               gamma: float, lam: float) -> torch.Tensor:
    """GAE(λ). ``rollout.starts[s]`` says obs[s] began a new episode, so step s − 1 does
    not bootstrap from it."""
    t = len(rollout.rewards)
    result = torch.zeros_like(rollout.rewards)
    last = torch.zeros_like(next_value)
    for s in reversed(range(t)):
        if s == t - 1:
            going = 1.0 - torch.as_tensor(next_done, dtype=torch.float32)
            following = next_value
        else:
            going, following = 1.0 - rollout.starts[s + 1], rollout.values[s + 1]
        delta = rollout.rewards[s] + gamma * following * going - rollout.values[s]
        last = delta + gamma * lam * going * last
        result[s] = last
    return result


def update(agent: Agent, optimizer: torch.optim.Optimizer, rollout: Rollout,
           adv: torch.Tensor, args: Args, rng: np.random.Generator) -> list[float]:
    """PPO's clipped objective over the rollout's minibatches; the losses."""
    targets = (adv + rollout.values).reshape(-1)
    obs, masks = rollout.obs.flatten(0, 1), rollout.masks.flatten(0, 1)
    actions, old_logprobs, adv = (rollout.actions.reshape(-1), rollout.logprobs.reshape(-1),
                                  adv.reshape(-1))
    size = len(actions)
    minibatch = size // args.num_minibatches
    losses = []
    for _ in range(args.update_epochs):
        order = rng.permutation(size)
        for first in range(0, size, minibatch):
            idx = torch.as_tensor(order[first:first + minibatch])
            dist = agent.distribution(obs[idx], masks[idx])  # the masks the actions had
            ratio = (dist.log_prob(actions[idx]) - old_logprobs[idx]).exp()
            a = adv[idx]
            a = (a - a.mean()) / (a.std() + 1e-8)
            clipped = ratio.clamp(1.0 - args.clip_coef, 1.0 + args.clip_coef)
            policy_loss = torch.max(-a * ratio, -a * clipped).mean()
            value_loss = 0.5 * (agent.value(obs[idx]) - targets[idx]).pow(2).mean()
            loss = policy_loss + args.vf_coef * value_loss - args.ent_coef * dist.entropy().mean()
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(agent.parameters(), args.max_grad_norm)
            optimizer.step()
            losses.append(loss.item())
    return losses


def count_invalid(info: dict[str, Any]) -> int:
    """Steps the env itself judged invalid: in the step's info, or, for a step that ended
    its episode, in the ``final_info`` that same_step autoreset moves that step's info to."""
    count = 0
    for record in (info, info.get("final_info", {})):
        if "invalid" in record:
            count += int(np.sum(record["invalid"] & record["_invalid"]))
    return count


def train(args: Args) -> dict[str, Any]:
    """Train for ``args.total_timesteps``; the agent, its state before, and counters."""
    torch.set_num_threads(args.torch_threads)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    envs = gym.make_vec(args.env_id, num_envs=args.num_envs,
                        vectorization_mode="vector_entry_point", autoreset_mode="same_step")
    obs_size = int(np.prod(envs.single_observation_space.shape))
    agent = Agent(obs_size, int(envs.single_action_space.n))
    untrained = copy.deepcopy(agent)
    optimizer = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)
    scale = ReturnScale(args.num_envs, args.gamma)
    n, t = args.num_envs, args.num_steps
    rollout = Rollout(t, n, obs_size, int(envs.single_action_space.n))
    updates = max(1, args.total_timesteps // (n * t))

    start = time.perf_counter()
    next_obs, info = envs.reset(seed=args.seed)
    next_mask, next_done = info["action_mask"], np.zeros(n, dtype=bool)
    episode_return, episode_returns = np.zeros(n), []
    steps = outside_mask = invalid = masked = 0
    losses: list[float] = []
    for iteration in range(updates):
        if args.anneal_lr:
            optimizer.param_groups[0]["lr"] = args.learning_rate * (1.0 - iteration / updates)
        for s in range(t):
            rollout.obs[s] = torch.as_tensor(next_obs, dtype=torch.float32)
            rollout.masks[s] = torch.as_tensor(next_mask, dtype=torch.bool)
            rollout.starts[s] = torch.as_tensor(next_done, dtype=torch.float32)
            with torch.no_grad():
                dist = agent.distribution(rollout.obs[s], rollout.masks[s])
                action = dist.sample()
                rollout.values[s] = agent.value(rollout.obs[s])
            rollout.actions[s], rollout.logprobs[s] = action, dist.log_prob(action)
            actions = action.numpy()
            masked += int((~next_mask).sum())  # branches the masks took away
            outside_mask += int((~next_mask[np.arange(n), actions]).sum())
            next_obs, reward, terminated, truncated, info = envs.step(actions)
            next_done = terminated | truncated
            next_mask = info["action_mask"]  # for an ended sub-env: its next episode's
            invalid += count_invalid(info)
            steps += n
            episode_return += reward
            episode_returns += episode_return[next_done].tolist()
            episode_return[next_done] = 0.0
            scaled = scale(reward, next_done) if args.normalize_reward else reward
            rollout.rewards[s] = torch.as_tensor(scaled, dtype=torch.float32)
        with torch.no_grad():
            next_value = agent.value(torch.as_tensor(next_obs, dtype=torch.float32))
        adv = advantages(rollout, next_value, next_done, args.gamma, args.gae_lambda)
        losses += update(agent, optimizer, rollout, adv, args, rng)
        recent = np.mean(episode_returns[-100:]) if episode_returns else float("nan")
        print(f"update {iteration + 1}/{updates}  steps {steps:,}  return (last 100 "
              f"episodes) {recent:.2f}  loss {losses[-1]:.4f}  "
              f"{time.perf_counter() - start:.1f} s", flush=True)
    envs.close()
    return {"agent": agent, "untrained": untrained, "steps": steps, "updates": updates,
            "seconds": time.perf_counter() - start, "losses": losses,
            "masked": masked, "outside_mask": outside_mask, "invalid": invalid,
            "episodes": len(episode_returns)}


def parse_args(argv: list[str] | None = None) -> Args:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    for name, default in asdict(Args()).items():
        flag = "--" + name.replace("_", "-")
        if isinstance(default, bool):
            parser.add_argument(flag, type=lambda text: text.lower() in ("1", "true", "yes"),
                                default=default, metavar="BOOL")
        else:
            parser.add_argument(flag, type=type(default), default=default)
    return Args(**vars(parser.parse_args(argv)))


def main(argv: list[str] | None = None) -> dict[str, Any]:
    args = parse_args(argv)
    run = train(args)
    # The project's evaluation loop takes any callable (obs, mask) -> action and plays it
    # beside the DP oracle and a uniformly random masked policy on the same held-out tasks.
    results = evaluate(args.env_id, {"masked_ppo": run["agent"].act,
                                     "untrained": run["untrained"].act, "random": "random"},
                       args.eval_episodes, TEST_SEED, held_out(args.env_id))
    print(f"{run['steps']:,} steps in {run['seconds']:.1f} s; "
          f"{args.eval_episodes} held-out tasks:")
    print(table(results))
    if args.save:
        torch.save(run["agent"].state_dict(), args.save)
    return {**run, "evaluation": results}


if __name__ == "__main__":
    main()
