"""How fast policies decide, as deployed: learned models beside receding_dp in one run.

    .venv/bin/python benchmarks/decisions.py [--env IKBranch/UR5e-v1] [--episodes 30]
        [--batch 16] [--model models/UR5e-v1/ppo.zip ...] [--horizon H]

Every policy plays the same held-out tasks (task seeds from ``envs.seeds.TEST_SEED``,
held-out scenes) on an env made fresh for it, so no path verdict or priced move another
policy left behind speeds it up, after one untimed warm-up episode on another task (first
calls load kernels and allocate). Then, per policy:

- **predict**: the wall time of each ``predict`` call, as ``agents.evaluation`` measures
  it: for a model SB3's ``predict`` (its input checks and conversions included) under
  ``torch.inference_mode``; for ``receding_dp`` its planning (its own path checks and
  pricing included: the env does not do them for it).
- **network, one**: a model's forward pass alone, one decision at a time, on the
  observations and masks it met (what a controller calling the network directly pays).
- **network, batched**: the decisions of ``--batch`` envs in one forward pass, per
  decision. ``receding_dp`` has no batched form: N decisions are N plans, so its batched
  time is its single one;
- **exported, one** and **exported, batched**: the same decisions by the model's actor
  exported for a controller (``agents.exported``: numpy alone, what ``ikbranch export``
  writes), one at a time and ``--batch`` at once; the run asserts that they are the
  model's decisions.

torch and numpy's BLAS each run one thread (a controller beside other work; on these
2-core machines a second thread only waits for the first).

The ratios are receding_dp's time over the policy's, from the same run. The run is
repeated with the policies in reverse order, and both are printed: the times must not
depend on what ran before. Numbers depend on the machine and its load.
"""

from __future__ import annotations

import os

# Before numpy is imported: its BLAS reads this once.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import glob
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import torch

import ikbranch_gym.envs as envs
from ikbranch_gym.agents.base import action_mask
from ikbranch_gym.agents.evaluation import build_policy
from ikbranch_gym.agents.exported import ExportedPolicy, exported_arrays
from ikbranch_gym.agents.sb3 import SB3Policy
from ikbranch_gym.envs.seeds import TEST_SEED, held_out


def play(env_id: str, spec: str, episodes: int, batch: int) -> dict:
    """``spec`` on a fresh env: per-decision predict times, and the observations and masks
    it decided on."""
    env = gym.make(env_id, **held_out(env_id))
    name, policy = build_policy(spec, env, TEST_SEED)
    times, observations, masks, actions = [], [], [], []
    for e in range(-1, episodes):  # e = −1: the warm-up
        observation, info = env.reset(seed=TEST_SEED - 1 if e < 0 else TEST_SEED + e)
        done, start = False, True
        while not done:
            mask = action_mask(env, info)
            tick = time.perf_counter()
            with torch.inference_mode():
                action, _ = policy.predict(observation, episode_start=np.array([start]),
                                           deterministic=True, action_masks=mask)
            spent = time.perf_counter() - tick
            if e >= 0:
                times.append(spent)
                observations.append(observation)
                masks.append(mask)
                actions.append(int(np.asarray(action)))
            observation, _, terminated, truncated, info = env.step(int(np.asarray(action)))
            done, start = bool(terminated or truncated), False
    env.close()
    row = {"name": name, "decisions": len(times), "predict": float(np.mean(times))}
    if isinstance(policy, SB3Policy):
        observed = np.asarray(observations, dtype=np.float32)
        allowed = np.asarray(masks, dtype=bool)
        row.update(network(policy, observed, allowed, batch))
        row.update(exported(policy, observed, allowed, np.asarray(actions), batch))
    return row


def exported(policy: SB3Policy, observations: np.ndarray, masks: np.ndarray,
             actions: np.ndarray, batch: int) -> dict:
    """The model's actor exported (``agents.exported``): seconds per decision, one at a
    time and ``batch`` at once, after asserting its decisions are the model's."""
    actor = ExportedPolicy(exported_arrays(policy.model))
    given = masks if actor.maskable else None
    decided = actor.decide_many(observations, given)
    assert np.array_equal(decided, actions), "the exported actor decided otherwise"

    def decide(rows: slice) -> None:
        actor.decide_many(observations[rows], None if given is None else given[rows])

    return {f"exported {label}": seconds
            for label, seconds in per_decision(decide, len(observations), batch).items()}


def network(policy: SB3Policy, observations: np.ndarray, masks: np.ndarray,
            batch: int) -> dict:
    """The forward pass alone: seconds per decision, one at a time and ``batch`` at once."""
    net = policy.model.policy
    net.set_training_mode(False)
    obs = torch.as_tensor(observations)
    mask = torch.as_tensor(masks)

    def decide(rows: slice) -> None:
        if policy.maskable:
            net(obs[rows], deterministic=True, action_masks=mask[rows])
        else:
            net(obs[rows], deterministic=True)

    with torch.inference_mode():
        return per_decision(decide, len(obs), batch)


def per_decision(decide: Callable[[slice], None], count: int, batch: int) -> dict:
    """Seconds per decision of ``decide`` (the decisions of a slice of ``count`` rows),
    ``one`` at a time and ``batched`` ``batch`` at once, each after an untimed call."""
    out = {}
    for label, size in (("one", 1), ("batched", batch)):
        decide(slice(0, size))  # warm-up
        tick = time.perf_counter()
        for start in range(0, count, size):
            decide(slice(start, start + size))
        out[label] = (time.perf_counter() - tick) / count
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="IKBranch/UR5e-v1")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--model", action="append", dest="models",
                        help="model zips (default: the committed models of --env)")
    parser.add_argument("--horizon", type=int, help="receding_dp's horizon (its default)")
    args = parser.parse_args()
    if args.env not in envs.ENV_IDS:
        parser.error(f"unknown env id {args.env!r}")
    torch.set_num_threads(1)
    models = args.models or sorted(glob.glob(f"models/{args.env.split('/')[1]}/*.zip"))
    planner = "receding_dp" + (f":{args.horizon}" if args.horizon else "")
    specs = [planner, *models]
    print(f"{args.env}, {args.episodes} held-out tasks, batches of {args.batch}; "
          "ms per decision\n")
    for order, sequence in (("as listed", specs), ("reversed", specs[::-1])):
        rows = {row["name"]: row for row in (play(args.env, s, args.episodes, args.batch)
                                              for s in sequence)}
        reference = rows[planner]["predict"]
        print(f"order: {order}\n")
        print("| policy | decisions | predict | × receding_dp | network, one "
              "| network, batched | × receding_dp, batched | exported, one | × receding_dp "
              "| exported, batched | × receding_dp |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for spec in specs:
            row = rows[spec.removesuffix(".zip")]
            one, batched = row.get("one"), row.get("batched", row["predict"])
            cells = []
            for label in ("exported one", "exported batched"):
                value = row.get(label)
                cells += ["", ""] if value is None else [f"{value * 1e3:.3f}",
                                                         f"{reference / value:.1f}"]
            print(f"| {row['name']} | {row['decisions']} | {row['predict'] * 1e3:.3f} "
                  f"| {reference / row['predict']:.1f} "
                  f"| {'' if one is None else f'{one * 1e3:.3f}'} | {batched * 1e3:.3f} "
                  f"| {reference / batched:.1f} | {' | '.join(cells)} |")
        print()


if __name__ == "__main__":
    main()
