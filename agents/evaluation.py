"""One evaluation loop for baselines and trained models, on shared task seeds.

Every policy gets its own fresh env (so no policy inherits another's collision cache and
its decision time is its own) and episode e of every policy is ``reset(seed=seed + e)``:
the same tasks for all. The DP oracle always runs, because the optimality gap of every
other policy is measured against it on those same tasks.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import ikbranch_gym.envs  # noqa: F401  (registers the env ids)

from . import BASELINES, make_baseline
from .base import Policy, unwrap

ORACLE = "dp_oracle"


@dataclass(frozen=True)
class Episode:
    """What one episode cost and how it ended."""

    reward: float  # the return: sum of the env's rewards
    travel: float  # rad-equivalents (prismatic joints at the env's prismatic_scale)
    time: float  # s
    steps: int
    success: bool
    collision: bool
    invalid: bool
    decision_seconds: float  # wall time inside predict, summed over the episode


def run_episode(policy: Policy, env: gym.Env, seed: int) -> Episode:
    """Play one episode of ``env`` reset with ``seed``, ``policy`` choosing deterministically."""
    obs, _ = env.reset(seed=seed)
    base = unwrap(env)
    state, start = None, True
    reward = travel = duration = decision = 0.0
    steps, collision, invalid, success = 0, False, False, False
    done = False
    while not done:
        masks = base.action_masks()
        tick = time.perf_counter()
        action, state = policy.predict(
            obs, state=state, episode_start=np.array([start]), deterministic=True,
            action_masks=masks,
        )
        decision += time.perf_counter() - tick
        obs, r, terminated, truncated, info = env.step(int(np.asarray(action).item()))
        start, done = False, terminated or truncated
        reward += float(r)
        travel += float(info["travel"])
        duration += float(info["time"])
        collision |= bool(info["collision"])
        invalid |= bool(info["invalid"])
        success = bool(info.get("is_success", False))
        steps += 1
    return Episode(reward, travel, duration, steps, success, collision, invalid, decision)


#: The baselines whose spec takes an argument after a colon: name -> (keyword, parse).
#: A parse raises ValueError for a value it refuses.
SPEC_ARGUMENTS: dict[str, tuple[str, Any]] = {
    "random": ("seed", lambda text: _integer(text, 0, "seed")),
    "receding_dp": ("horizon", lambda text: _integer(text, 1, "horizon")),
    "fixed": ("branch", str),  # an index or a label: the baseline checks it against the arm
}


def _integer(text: str, minimum: int, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = minimum - 1
    if value < minimum:
        raise ValueError(f"the argument is a {what} (an integer >= {minimum}), got {text!r}")
    return value


def parse_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """A baseline spec (``name`` or ``name:argument``) as ``(name, keyword arguments)``,
    checked without an env: ``ValueError`` for an unknown name, an argument the baseline
    does not take, or a value it refuses (see :func:`build_policy`)."""
    name, colon, argument = spec.partition(":")
    if name not in BASELINES:
        raise ValueError(f"unknown baseline {name!r}; choose one of {', '.join(BASELINES)}")
    if not colon:
        return name, {}
    if name not in SPEC_ARGUMENTS:
        raise ValueError(f"baseline {name!r} takes no argument, got {spec!r}")
    keyword, parse = SPEC_ARGUMENTS[name]
    return name, {keyword: parse(argument)}


def build_policy(spec: str, env: gym.Env, seed: int) -> tuple[str, Policy]:
    """``(name, policy)`` for a command-line spec bound to ``env``.

    A spec is a path ending in ``.zip`` (an SB3 model; its name is the path without
    ``.zip``: training writes every run's model as ``model.zip``) or a
    baseline name with an optional argument after a colon (``SPEC_ARGUMENTS``):
    ``fixed:2`` or ``fixed:back/elbow-up/wrist+`` (the branch), ``receding_dp:4`` (the
    horizon), ``random:7`` (the generator's seed; default the evaluation seed).
    """
    if spec.endswith(".zip"):
        from .sb3 import SB3Policy  # torch is imported only when a model is evaluated

        return spec.removesuffix(".zip"), SB3Policy.load(spec, env)
    name, kwargs = parse_spec(spec)
    if name == "random":
        kwargs.setdefault("seed", seed)
    return spec, make_baseline(name, env, **kwargs)


def summarise(episodes: list[Episode], oracle_return: float | None = None) -> dict[str, Any]:
    """The metrics of one policy; ``optimality_gap`` needs the oracle's mean return."""
    rewards = np.array([e.reward for e in episodes])
    travel = np.array([e.travel for e in episodes])
    durations = np.array([e.time for e in episodes])
    steps = sum(e.steps for e in episodes)
    mean_return = float(rewards.mean())
    gap = None
    if oracle_return is not None and oracle_return != 0.0:
        gap = (oracle_return - mean_return) / abs(oracle_return)
    elif oracle_return is not None:
        gap = 0.0 if mean_return == oracle_return else None  # no scale to measure against
    return {
        "success_rate": float(np.mean([e.success for e in episodes])),
        "mean_return": mean_return,
        "std_return": float(rewards.std()),
        "mean_travel": float(travel.mean()),
        "std_travel": float(travel.std()),
        "mean_travel_deg": float(np.degrees(travel.mean())),
        "mean_time": float(durations.mean()),
        "std_time": float(durations.std()),
        "collision_rate": float(np.mean([e.collision for e in episodes])),
        "invalid_rate": float(np.mean([e.invalid for e in episodes])),
        "optimality_gap": gap,
        "mean_steps": steps / len(episodes),
        # Wall time per decision, planning included: a planner's reset-time work is done
        # inside its first predict call, so this is its planning cost amortised per step.
        "decision_ms": 1e3 * sum(e.decision_seconds for e in episodes) / steps,
        "returns": rewards.tolist(),
        "successes": [bool(e.success) for e in episodes],
    }


def evaluate(
    env_id: str,
    policies: list[str],
    episodes: int,
    seed: int,
    env_kwargs: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Evaluate every policy spec on episodes seeded ``seed, seed + 1, …``.

    Returns ``{"env", "env_kwargs", "episodes", "seed", "policies": {name: metrics}}``,
    the oracle included (run first, whether asked for or not).
    """
    if episodes < 1:
        raise ValueError("episodes must be >= 1")
    env_kwargs = dict(env_kwargs or {})
    specs = [ORACLE, *(spec for spec in policies if spec != ORACLE)]
    # Build every policy before playing any, so a bad spec or model fails at once.
    opened: list[gym.Env] = []
    players: dict[str, tuple[gym.Env, Policy]] = {}
    try:
        for spec in specs:
            opened.append(env := gym.make(env_id, **env_kwargs))
            name, policy = build_policy(spec, env, seed)
            unique, copy = name, 2
            while unique in players:  # the same spec or model twice
                unique, copy = f"{name}#{copy}", copy + 1
            players[unique] = (env, policy)
        runs = {
            name: [run_episode(policy, env, seed + e) for e in range(episodes)]
            for name, (env, policy) in players.items()
        }
    finally:
        for env in opened:
            env.close()
    oracle_return = float(np.mean([e.reward for e in runs[ORACLE]]))
    return {
        "env": env_id,
        "env_kwargs": env_kwargs,
        "episodes": episodes,
        "seed": seed,
        "policies": {name: summarise(eps, oracle_return) for name, eps in runs.items()},
    }
