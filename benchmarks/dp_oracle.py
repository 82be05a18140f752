"""The DP oracle on a long task: planning time, where it goes, and that the env pays the plan.

    .venv/bin/python benchmarks/dp_oracle.py [--waypoints 1000] [--task tool_changes] [--seed 0]

Default: the anthropomorphic arm in the milling cell (``IKBranch/ToolTransfer-v0``), 1,000
tool-change waypoints. The oracle prices every edge's travel and time, and checks
collisions lazily (``agents/dp.py``: only edges that can still lie on the best path).
*Cold* is the first plan on a fresh env (empty move caches; numba's compile cache warm),
*warm* a re-plan with the caches full. ``--task random`` draws distinct poses in the same
cell, where no path repeats.

Printed: cold and warm planning, the time in path checks and in pricing + DP, how many
edges were checked; the DP backward pass alone over fully priced edges
(``ladder_q_tables``, the reference the lazy planner is tested equal to); every unique
edge checked in one call, for scale (what pricing every edge would cost); then the
episode replayed through ``step``, its return compared with the planned one.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import ikbranch_gym.envs  # noqa: F401
from ikbranch_gym.agents import DPOracle, ladder_q_tables


class Stopwatch:
    """Wraps a callable and sums the wall time and calls spent in it."""

    def __init__(self, function) -> None:
        self.function, self.seconds, self.calls = function, 0.0, 0

    def __call__(self, *args, **kwargs):
        tick = time.perf_counter()
        try:
            return self.function(*args, **kwargs)
        finally:
            self.seconds += time.perf_counter() - tick
            self.calls += 1


def plan(env, label: str) -> DPOracle:
    """Plan once with a fresh oracle, timing the whole and the path checks inside it."""
    base = env.unwrapped
    checks = Stopwatch(base.checker.rows_paths_collide)
    base.checker.rows_paths_collide = checks  # an instance attribute shadows the method
    try:
        oracle = DPOracle(env)
        tick = time.perf_counter()
        oracle.on_episode()
        total = time.perf_counter() - tick
    finally:
        del base.checker.rows_paths_collide
    print(f"{label:<6} plan {total:7.3f} s   path checks {checks.seconds:7.3f} s "
          f"({checks.calls} batched calls, {oracle.lazy.checks} edges checked lazily)   "
          f"pricing and DP {total - checks.seconds:7.3f} s")
    return oracle


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--waypoints", type=int, default=1000)
    parser.add_argument("--task", default="tool_changes", choices=["tool_changes", "random"])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    tick = time.perf_counter()
    env = gym.make("IKBranch/ToolTransfer-v0", task=args.task, n_waypoints=args.waypoints)
    obs, _ = env.reset(seed=args.seed)
    base = env.unwrapped
    n, k = base.task.n_waypoints, base.arm.n_branches
    print(f"IKBranch/ToolTransfer-v0 task={args.task}: {n} waypoints × {k} branches, "
          f"{k + (n - 1) * k * k} edges; env build + reset {time.perf_counter() - tick:.2f} s")

    oracle = plan(env, "cold")
    checked = len(base.pricer.paths)
    plan(env, "warm")

    edges = [base.edge_rewards(i) for i in range(n)]  # every edge priced and checked
    tick = time.perf_counter()
    ladder_q_tables(edges, base.valid)
    print(f"DP backward pass alone (ladder_q_tables, every edge priced) "
          f"{1e3 * (time.perf_counter() - tick):.1f} ms")

    # The same unique paths in one call: the floor an env pricing edges in bulk could reach.
    pairs: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
    for i in range(n):
        rows = [base.task.start] if i == 0 else list(base.candidates[i - 1])
        for q0 in rows:
            for q1 in base.candidates[i]:
                if np.isfinite(q0).all() and np.isfinite(q1).all():
                    pairs.setdefault(q0.tobytes() + q1.tobytes(), (q0, q1))
    q0s = np.array([p[0] for p in pairs.values()])
    q1s = np.array([p[1] for p in pairs.values()])
    tick = time.perf_counter()
    base.checker.paths_collide(q0s, q1s)
    print(f"all {len(pairs)} unique paths in one paths_collide call: "
          f"{time.perf_counter() - tick:.3f} s (the lazy cold plan checked {checked})")

    # The env still stands at the start of the planned task: replay the plan through step.
    paid, done, steps = 0.0, False, 0
    tick = time.perf_counter()
    while not done:
        action, _ = oracle.predict(obs)
        obs, reward, done, _, _ = env.step(action)
        paid += reward
        steps += 1
    print(f"replay {steps} steps in {time.perf_counter() - tick:.2f} s: return {paid:.6f}, "
          f"planned {oracle.planned_return:.6f}, |difference| "
          f"{abs(paid - oracle.planned_return):.1e}")


if __name__ == "__main__":
    main()
