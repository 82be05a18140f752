"""Environment throughput: steps/s of every registered id, next to Gymnasium's Reacher-v5.

    MUJOCO_GL=egl .venv/bin/python benchmarks/env_steps.py [--seconds 3] [--ids ID ...]

Single process: random *masked* actions (uniform over ``action_masks()``), drawn from a
seeded generator; ``Reacher-v5`` takes ``action_space.sample()``. After a warm-up (which
fills the env's path-collision cache: ``--warmup`` seconds or steps, whichever ends
first), the loop runs for ``--seconds``. Two numbers per id:

- ``step/s``: steps per second of time spent *inside* ``step()`` only;
- ``step+reset/s``: steps per second of the whole loop, resets (and mask queries)
  included: the throughput a learner sees. ``ms/reset`` is the mean reset time.

Vector: ``gym.make_vec(id, num_envs=2, vectorization_mode="async")`` (two worker
processes), masks fetched every step with ``envs.call("action_masks")`` as MaskablePPO
does; steps counted per sub-env (2 per vector step), resets included (auto-reset).
Numbers depend on the machine and its load; ToolTransfer's target is 5,000 steps/s on
one core in steady state.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("MUJOCO_GL", "egl")

import gymnasium as gym
import numpy as np

import envs
from envs.models import TREE_BUILDERS


def _available(env_id: str) -> bool:
    return env_id not in envs.ENV_SPECS or envs.ENV_SPECS[env_id]["arm"] in TREE_BUILDERS


def single(env_id: str, seconds: float, warmup: float, warmup_steps: int) -> dict:
    env = gym.make(env_id)
    rng = np.random.default_rng(0)
    masked = hasattr(env.unwrapped, "action_masks")

    def action():
        if masked:
            return int(rng.choice(np.flatnonzero(env.unwrapped.action_masks())))
        return env.action_space.sample()

    env.reset(seed=0)
    env.action_space.seed(0)
    start = time.perf_counter()
    for _ in range(warmup_steps):
        _, _, terminated, truncated, _ = env.step(action())
        if terminated or truncated:
            env.reset()
        if time.perf_counter() - start > warmup:
            break
    steps = resets = 0
    in_step = in_reset = 0.0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        a = action()
        t0 = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(a)
        t1 = time.perf_counter()
        in_step += t1 - t0
        steps += 1
        if terminated or truncated:
            env.reset()
            in_reset += time.perf_counter() - t1
            resets += 1
    total = time.perf_counter() - start
    env.close()
    return {
        "step/s": steps / in_step,
        "step+reset/s": steps / total,
        "ms/reset": 1e3 * in_reset / max(resets, 1),
        "steps/episode": steps / max(resets, 1),
    }


def vector(env_id: str, seconds: float, warmup: float) -> float:
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="async")
    rng = np.random.default_rng(0)
    masked = env_id in envs.ENV_SPECS
    venv.reset(seed=0)
    venv.action_space.seed(0)

    def actions():
        if not masked:
            return venv.action_space.sample()
        masks = venv.call("action_masks")
        return np.array([rng.choice(np.flatnonzero(m)) for m in masks])

    start = time.perf_counter()
    while time.perf_counter() - start < warmup:
        venv.step(actions())
    steps = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        venv.step(actions())
        steps += venv.num_envs
    total = time.perf_counter() - start
    venv.close()
    return steps / total


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=3.0, help="timed loop per case")
    parser.add_argument("--warmup", type=float, default=20.0, help="warm-up limit, seconds")
    parser.add_argument("--warmup-steps", type=int, default=20000, help="warm-up limit, steps")
    parser.add_argument("--no-vector", action="store_true", help="skip the make_vec column")
    parser.add_argument("--ids", nargs="*", default=None, help="ids (default: all + Reacher-v5)")
    args = parser.parse_args()
    ids = args.ids or [*envs.ENV_IDS, "Reacher-v5"]

    print(f"{os.cpu_count()} CPUs; timed {args.seconds:g} s per case after warm-up "
          f"(≤ {args.warmup:g} s / {args.warmup_steps} steps)\n")
    print("| id | step/s (in step) | step+reset/s | ms/reset | steps/episode "
          "| make_vec async ×2, steps/s |")
    print("|---|---:|---:|---:|---:|---:|")
    for env_id in ids:
        if not _available(env_id):
            print(f"| {env_id} | n/a: no MuJoCo model for its arm yet | | | | |")
            continue
        row = single(env_id, args.seconds, args.warmup, args.warmup_steps)
        # The same warm-up as the single case: the workers' path caches start cold too.
        vec = "—" if args.no_vector else f"{vector(env_id, args.seconds, args.warmup):,.0f}"
        print(f"| {env_id} | {row['step/s']:,.0f} | {row['step+reset/s']:,.0f} "
              f"| {row['ms/reset']:.2f} | {row['steps/episode']:.1f} | {vec} |", flush=True)


if __name__ == "__main__":
    main()
