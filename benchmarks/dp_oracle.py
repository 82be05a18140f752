"""The DP oracle on a long task: planning time, where it goes, and that the env pays the plan.

    .venv/bin/python benchmarks/dp_oracle.py [--waypoints 1000] [--task tool_changes] [--seed 0]

Default: the anthropomorphic arm in the milling cell (``IKBranch/ToolTransfer-v0``), 1,000
tool-change waypoints, every edge (every K×K move, and the K first moves) priced by
``env.edge_rewards`` with its path collision-checked. Tool-change poses repeat (3 rack
slots and the spindle) and the env caches path checks per configuration pair, so only a
few hundred edges are unique: *cold* is the first plan on a fresh env, *warm* a re-plan
with the env's cache full. ``--task random`` draws 1,000 distinct poses in the same cell,
where every edge is unique and must be checked (the ladder-graph planner's real job).

Printed: cold and warm planning (all ``edge_rewards`` + the backward pass), the time in
path checks, in the env's per-edge Python, and in the DP itself; then the same unique
paths checked in one batched call (what an env that priced a waypoint's K×K edges in one
``check_paths`` call would pay); then the episode replayed through ``step``, its return
compared with the planned one.

Recorded on the 2-core dev machine, quiet, after the tool-change task gained approach
poses, grips and parked starts (1,000 waypoints: 63,944 edges, 1,928 unique paths): cold
plan 4.31 s, of which path checks 3.92 s; warm plan 0.33 s (the env's per-edge Python);
the DP backward pass 6.5 ms; replayed return = planned return exactly. The earlier
two-pose task (392 unique paths) planned cold in 1.0–2.3 s under load. ``--task random``
(50 waypoints, every edge unique) took 30 s cold, all path checks (~11 ms per path):
1,000 such waypoints would take ~12 min.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import envs  # noqa: F401
from agents import DPOracle, ladder_q_tables


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
    checks = Stopwatch(base.checker.check_paths)
    base.checker.check_paths = checks  # instance attribute shadows the method: timing only
    try:
        oracle = DPOracle(env)
        tick = time.perf_counter()
        oracle.on_episode()
        total = time.perf_counter() - tick
    finally:
        del base.checker.check_paths
    print(f"{label:<6} plan {total:7.3f} s   path checks {checks.seconds:7.3f} s "
          f"({checks.calls} batched calls)   env per-edge Python and DP "
          f"{total - checks.seconds:7.3f} s")
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
    unique = len(base.pricer.paths)
    plan(env, "warm")

    edges = [base.edge_rewards(i) for i in range(n)]
    tick = time.perf_counter()
    ladder_q_tables(edges, base.valid)
    print(f"DP backward pass alone {1e3 * (time.perf_counter() - tick):.1f} ms")

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
    base.checker.check_paths(q0s, q1s)
    print(f"{len(pairs)} unique paths ({unique} in the env's cache) in one check_paths call: "
          f"{time.perf_counter() - tick:.3f} s")

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
