"""Environment throughput: steps/s of every registered id, next to Gymnasium's Reacher-v5.

    MUJOCO_GL=egl .venv/bin/python benchmarks/env_steps.py [--seconds 3] [--ids ID ...]
                                                           [--num-envs 16] [--threads 2]
                                                           [--async]

Single process, random *masked* actions (uniform over the valid branches) from a seeded
generator; ``Reacher-v5`` takes ``action_space.sample()``. Resets are part of every loop.
Columns per id:

- the single env: ``cold``, steps/s over the first ``--seconds`` of a fresh env (empty
  move caches, the numba kernels already compiled on disk): what a new run sees first;
  then, after a warm-up (``--warmup`` seconds or steps, whichever ends first, which fills
  the caches of tasks with a finite pose set), ``in step``: steps per second of time
  inside ``step()`` only; ``with resets``: steps per second of the whole loop, resets and
  mask queries included (the throughput a learner sees); ``× Reacher``: that figure over
  Reacher-v5's (single env) in the same run; ``ms/reset``; ``steps/episode``;
- ``vector``: the natively batched vector env, ``gym.make_vec(id, num_envs=N,
  vectorization_mode="vector_entry_point", autoreset_mode="same_step")`` in this
  process, masks from ``info["action_mask"]``, steps counted per sub-env, after the same
  warm-up; ``× Reacher`` over Reacher-v5's *single* env;
- ``oracle``: the same vector env playing dp_oracle's plan (planned at each reset, the
  planning time not counted): full-length episodes, as a trained policy plays them;
- ``threads``: both again with the vector env's sub-envs in ``--threads`` groups stepped
  in as many threads (``threads=T``; 0 leaves the columns out);
- ``--async``: ``vectorization_mode="async"`` with one and with two worker processes,
  masks from ``info["action_mask"]`` (no round trip), steps counted per sub-env, and the
  two workers' rate over the one worker's; beside it ``lockstep``, what that ratio
  would be if a call cost only the env's own work, on two free cores: a worker's calls
  are timed in this process (a step, or after an episode's end the reset that
  next-step autoreset makes of the next call), and a call of two workers takes the
  slower of two such calls, drawn at random from them. Where the env's work dominates,
  the measured ratio stays below it; where the pipes' round trip does, one worker pays
  it on every call and two overlap theirs, so the measured ratio may exceed it.

Numbers depend on the machine and its load: compare rows of one run.
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium as gym
import numpy as np

import ikbranch_gym.envs as envs


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


def _masked(masks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Per row a uniformly random branch among ``masks``' True ones."""
    return (rng.random(masks.shape) * masks).argmax(axis=1)


def vector(env_id: str, num_envs: int, seconds: float, warmup: float,
           oracle: bool = False, threads: int = 1) -> float:
    """Steps/s of the native vector env (its sub-envs in ``threads`` threads), every
    sub-env's step counted: random masked actions, or with ``oracle`` dp_oracle's plans
    (their planning time not counted)."""
    from ikbranch_gym.agents.dp import LazyLadder

    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode="same_step", threads=threads)
    subs = venv.unwrapped.envs
    rng = np.random.default_rng(0)
    _, info = venv.reset(seed=0)
    plans: list[list[int]] = [[] for _ in subs]
    planning = 0.0

    def replan(rows) -> None:
        nonlocal planning
        start = time.perf_counter()
        for i in rows:
            plans[i] = LazyLadder(subs[i].ladder).plan(0, subs[i].n_waypoints, 0)[1]
        planning += time.perf_counter() - start

    def run(limit: float) -> float:
        nonlocal info, planning
        if oracle:
            replan(range(len(subs)))
        steps, planning = 0, 0.0
        start = time.perf_counter()
        while time.perf_counter() - start - planning < limit:
            if oracle:
                actions = np.array([plan[min(sub.index, len(plan) - 1)]
                                    for plan, sub in zip(plans, subs, strict=True)])
            else:
                actions = _masked(info["action_mask"], rng)
            _, _, terminated, _, info = venv.step(actions)
            steps += len(subs)
            if oracle and terminated.any():
                replan(np.flatnonzero(terminated))
        return steps / (time.perf_counter() - start - planning)

    run(warmup)
    rate = run(seconds)
    venv.close()
    return rate


def async_workers(env_id: str, workers: int, seconds: float, warmup: float) -> float:
    """Steps/s of ``make_vec(..., "async")`` with ``workers`` workers (a sub-env each),
    every sub-env's steps counted."""
    venv = gym.make_vec(env_id, num_envs=workers, vectorization_mode="async")
    rng = np.random.default_rng(0)
    masked = env_id in envs.ENV_SPECS
    _, info = venv.reset(seed=0)
    venv.action_space.seed(0)

    def actions():
        return _masked(info["action_mask"], rng) if masked else venv.action_space.sample()

    start = time.perf_counter()
    while time.perf_counter() - start < warmup:
        _, _, _, _, info = venv.step(actions())
    steps = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        _, _, _, _, info = venv.step(actions())
        steps += venv.num_envs
    total = time.perf_counter() - start
    venv.close()
    return steps / total


def lockstep(env_id: str, seconds: float, warmup: float) -> float:
    """The rate of two workers stepped in lockstep over one's, counting only the env's
    own work (the module docstring)."""
    env = gym.make(env_id)
    env.reset(seed=0)
    env.action_space.seed(0)
    action = _runner(env, 0)
    ended, calls = False, []
    start = time.perf_counter()
    while time.perf_counter() - start < warmup + seconds:
        a = None if ended else action()
        t0 = time.perf_counter()
        if ended:
            env.reset()
            ended = False
        else:
            _, _, terminated, truncated, _ = env.step(a)
            ended = terminated or truncated
        if t0 - start >= warmup:
            calls.append(time.perf_counter() - t0)
    env.close()
    cost, rng = np.array(calls), np.random.default_rng(0)
    pairs = np.maximum(rng.choice(cost, 100_000), rng.choice(cost, 100_000))
    return 2.0 * cost.mean() / pairs.mean()


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=3.0, help="timed loop per case")
    parser.add_argument("--warmup", type=float, default=10.0, help="warm-up limit, seconds")
    parser.add_argument("--warmup-steps", type=int, default=20000, help="warm-up limit, steps")
    parser.add_argument("--num-envs", type=int, default=16, help="sub-envs of the vector env")
    parser.add_argument("--threads", type=int, default=2,
                        help="threads of the vector env's second columns (0: none)")
    parser.add_argument("--async", dest="asynchronous", action="store_true",
                        help="add the make_vec async columns (one and two workers)")
    parser.add_argument("--ids", nargs="*", default=None, help="ids (default: all)")
    args = parser.parse_args()
    ids = args.ids or list(envs.ENV_IDS)

    print(f"{os.cpu_count()} CPUs; {args.seconds:g} s per column, warm-up ≤ {args.warmup:g} s "
          f"/ {args.warmup_steps} steps; vector env of {args.num_envs}\n")
    reacher = single("Reacher-v5", args.seconds, args.warmup, args.warmup_steps)
    base = reacher["step+reset/s"]
    threads = [1, args.threads] if args.threads > 1 else [1]
    print("| id | single: cold | in step | with resets | × Reacher | ms/reset | steps/episode "
          "| vector: with resets | × Reacher | oracle actions | × Reacher |"
          + (f" {args.threads} threads: with resets | × Reacher | oracle actions "
             "| × Reacher |" if len(threads) > 1 else "")
          + (" async ×1 | async ×2 | ×2 / ×1 | lockstep |" if args.asynchronous
             else ""))
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
          + ("---:|---:|---:|---:|" if len(threads) > 1 else "")
          + ("---:|---:|---:|---:|" if args.asynchronous else ""))
    for env_id in [*ids, "Reacher-v5"]:
        row = reacher if env_id == "Reacher-v5" else single(
            env_id, args.seconds, args.warmup, args.warmup_steps)
        line = (f"| {env_id} | {row['cold']:,.0f} | {row['step/s']:,.0f} "
                f"| {row['step+reset/s']:,.0f} | {row['step+reset/s'] / base:.2f} "
                f"| {row['ms/reset']:.2f} | {row['steps/episode']:.1f} |")
        if env_id in envs.ENV_SPECS:
            rates = [vector(env_id, args.num_envs, args.seconds, args.warmup, oracle, count)
                     for count in threads for oracle in (False, True)]
            line += "".join(f" {rate:,.0f} | {rate / base:.2f} |" for rate in rates)
        else:
            line += " | |" * 2 * len(threads)
        if args.asynchronous:
            one, two = (async_workers(env_id, workers, args.seconds, args.warmup)
                        for workers in (1, 2))
            model = lockstep(env_id, args.seconds, args.warmup)
            line += f" {one:,.0f} | {two:,.0f} | {two / one:.2f} | {model:.2f} |"
        print(line, flush=True)


if __name__ == "__main__":
    main()
