"""Environment throughput: steps/s of every registered id, next to Gymnasium's Reacher-v5.

    MUJOCO_GL=egl .venv/bin/python benchmarks/env_steps.py [--seconds 3] [--ids ID ...]
                                                           [--vector]

Single process, random *masked* actions (uniform over ``action_masks()``) from a seeded
generator; ``Reacher-v5`` takes ``action_space.sample()``. Resets are part of every loop.
Columns per id:

- ``cold``: steps/s over the first ``--seconds`` of a fresh env (empty move caches, the
  numba kernels already compiled on disk): what a new run sees first;
- then, after a warm-up (``--warmup`` seconds or steps, whichever ends first, which fills
  the caches of tasks with a finite pose set), ``in step``: steps per second of time
  inside ``step()`` only; ``with resets``: steps per second of the whole loop, resets and
  mask queries included (the throughput a learner sees); ``× Reacher``: that figure over
  Reacher-v5's in the same run; ``ms/reset``; ``steps/episode``.
- ``--vector``: ``gym.make_vec(id, num_envs=2, vectorization_mode="async")`` (two worker
  processes), masks fetched every step as MaskablePPO does, steps counted per sub-env.

Numbers depend on the machine and its load: compare rows of one run.
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium as gym
import numpy as np

import envs


def _runner(env, seed: int):
    rng = np.random.default_rng(seed)
    masked = hasattr(env.unwrapped, "action_masks")

    def action():
        if masked:
            return int(rng.choice(np.flatnonzero(env.unwrapped.action_masks())))
        return env.action_space.sample()

    return action


def _loop(env, action, seconds: float, max_steps: int | None = None) -> dict:
    steps = resets = 0
    in_step = in_reset = 0.0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds and (max_steps is None or steps < max_steps):
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
    return {
        "steps": steps, "resets": resets, "seconds": total, "in step": in_step,
        "in reset": in_reset,
        "step/s": steps / in_step if in_step else float("nan"),
        "step+reset/s": steps / total,
        "ms/reset": 1e3 * in_reset / max(resets, 1),
        "steps/episode": steps / max(resets, 1),
    }


def single(env_id: str, seconds: float, warmup: float, warmup_steps: int) -> dict:
    env = gym.make(env_id)
    env.reset(seed=0)
    env.action_space.seed(0)
    action = _runner(env, 0)
    cold = _loop(env, action, seconds)["step+reset/s"]
    _loop(env, action, warmup, warmup_steps)
    row = _loop(env, action, seconds)
    env.close()
    return {"cold": cold, **row}


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
    parser.add_argument("--warmup", type=float, default=10.0, help="warm-up limit, seconds")
    parser.add_argument("--warmup-steps", type=int, default=20000, help="warm-up limit, steps")
    parser.add_argument("--vector", action="store_true", help="add the make_vec column")
    parser.add_argument("--ids", nargs="*", default=None, help="ids (default: all)")
    args = parser.parse_args()
    ids = args.ids or list(envs.ENV_IDS)

    print(f"{os.cpu_count()} CPUs; {args.seconds:g} s per column, warm-up ≤ {args.warmup:g} s "
          f"/ {args.warmup_steps} steps\n")
    reacher = single("Reacher-v5", args.seconds, args.warmup, args.warmup_steps)
    header = ("| id | cold, with resets | in step | with resets | × Reacher | ms/reset "
              "| steps/episode |")
    print(header + (" make_vec async ×2 |" if args.vector else ""))
    print("|---|---:|---:|---:|---:|---:|---:|" + ("---:|" if args.vector else ""))
    for env_id in [*ids, "Reacher-v5"]:
        row = reacher if env_id == "Reacher-v5" else single(
            env_id, args.seconds, args.warmup, args.warmup_steps)
        ratio = row["step+reset/s"] / reacher["step+reset/s"]
        line = (f"| {env_id} | {row['cold']:,.0f} | {row['step/s']:,.0f} "
                f"| {row['step+reset/s']:,.0f} | {ratio:.2f} | {row['ms/reset']:.2f} "
                f"| {row['steps/episode']:.1f} |")
        if args.vector:
            line += f" {vector(env_id, args.seconds, args.warmup):,.0f} |"
        print(line, flush=True)


if __name__ == "__main__":
    main()
