"""Where an env's time goes: per id, one episode of masked random actions, split by stage.

    .venv/bin/python benchmarks/env_budget.py [--seconds 3] [--ids ID ...]

The loop of ``env_steps.py`` (random *masked* actions from a seeded generator, resets
included), after a warm-up of ``--warmup`` seconds, with each stage timed per episode (ms):

- ``scene``: laying the per-episode clutter and refreshing the collision filter;
- ``task``: drawing the task (for random reachable waypoints the compiled chain of
  collision-free configurations and paths, ``envs/random_chain.py``, and its poses);
- ``candidates``: every waypoint's IK and the configuration check of every candidate
  (``envs/resets.py``);
- ``reset, rest``: the rest of ``reset`` (observation templates, the first observation);
- ``steps``: all ``step`` calls of the episode (their path checks, prices, observations);
- per episode, who decided the samples the filter saw: the lanes (samples they bounded,
  and of them those they proved in contact; those they proved neither way go on to the
  scalar kernel and are counted there too),
  the scalar kernel's bounds (proved free), its witnesses (inner shapes that proved a
  contact) and MuJoCo (the rest), and how many of MuJoCo's checks found no contact
  (samples free that the bounds could not prove free).

Numbers depend on the machine and its load: compare rows of one run.
"""

from __future__ import annotations

import argparse
import functools
import os
import time

import gymnasium as gym
import numpy as np
from env_steps import _loop, _runner

import ikbranch_gym.envs as envs
import ikbranch_gym.envs.resets as resets
from ikbranch_gym.envs.models.filter import COUNTERS

#: Stage name -> seconds spent, filled by the timers below.
SPENT: dict[str, float] = {}


def _timed(stage: str, function):
    @functools.wraps(function)
    def timed(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            SPENT[stage] = SPENT.get(stage, 0.0) + time.perf_counter() - start

    return timed


# The stages of a reset (envs/resets.py): the tasks drawn, the ladders solved.
resets._draw_tasks = _timed("task", resets._draw_tasks)
resets._solve = _timed("candidates", resets._solve)


def budget(env_id: str, seconds: float, warmup: float) -> dict:
    env = gym.make(env_id)
    base = env.unwrapped
    base._lay_scene = _timed("scene", base._lay_scene)
    base.pricer.task = _timed("candidates", base.pricer.task)  # tasks of finite pose sets
    env.reset(seed=0)
    action = _runner(env, 0)
    counters = base.checker._filter.counters if base.checker._filter is not None else None
    _loop(env, action, warmup)
    SPENT.clear()
    before = None if counters is None else counters.copy()
    run = _loop(env, action, seconds)
    episodes = max(run["resets"], 1)
    per = 1e3 / episodes
    row = {stage: SPENT.get(stage, 0.0) * per for stage in ("scene", "task", "candidates")}
    row["rest"] = run["in reset"] * per - row["scene"] - row["task"] - row["candidates"]
    row["steps"] = run["in step"] * per
    row["episode"] = run["seconds"] * per
    row["step/s"], row["steps/episode"] = run["step+reset/s"], run["steps/episode"]
    counts = (np.zeros(len(COUNTERS)) if counters is None else counters - before) / episodes
    count = dict(zip(COUNTERS, counts, strict=True))
    row["proved free"] = count["bounded"] - count["mujoco"] - count["witnessed"]
    row["witnessed"], row["mujoco"] = count["witnessed"], count["mujoco"]
    row["free"], row["lanes"] = count["mujoco found free"], count["lane samples"]
    row["lane contacts"] = count["lane contacts"]
    env.close()
    return row


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=3.0, help="timed loop per id")
    parser.add_argument("--warmup", type=float, default=1.0, help="warm-up per id, seconds")
    parser.add_argument("--ids", nargs="*", default=None, help="ids (default: all)")
    args = parser.parse_args()
    ids = args.ids or list(envs.ENV_IDS)
    print(f"{os.cpu_count()} CPUs; {args.seconds:g} s per id after {args.warmup:g} s of "
          "warm-up; ms per episode unless stated\n")
    print("| id | steps/s with resets | steps/episode | episode | scene | task | candidates "
          "| reset, rest | steps | lane samples | of them in contact "
          "| scalar samples proved free | witnessed | MuJoCo checks | of them free |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for env_id in ids:
        r = budget(env_id, args.seconds, args.warmup)
        print(f"| {env_id} | {r['step/s']:,.0f} | {r['steps/episode']:.1f} | {r['episode']:.2f} "
              f"| {r['scene']:.2f} | {r['task']:.2f} | {r['candidates']:.2f} | {r['rest']:.2f} "
              f"| {r['steps']:.2f} | {r['lanes']:,.0f} | {r['lane contacts']:,.1f} "
              f"| {r['proved free']:,.0f} "
              f"| {r['witnessed']:,.1f} | {r['mujoco']:,.1f} | {r['free']:,.1f} |", flush=True)


if __name__ == "__main__":
    main()
