"""Collision-check throughput: batched (mujoco.batch) vs a plain Python loop, and path checks.

    .venv/bin/python benchmarks/collision_throughput.py [--configs 20000] [--repeats 3]

Configurations are uniform in the anthropomorphic arm's joint limits, in the milling cell
(the densest scene). The path is the paper's 1.1 → 2.1 transfer at the default resolution.
Best of ``--repeats`` runs; numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from envs.kinematics import make_arm
from envs.models import RECOMMENDED_BRANCHES, CollisionChecker, build_model, milling_cell_poses


def _best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--configs", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    arm = make_arm("anthropomorphic")
    model = build_model("anthropomorphic", "milling_cell")
    rng = np.random.default_rng(0)
    q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], size=(args.configs, arm.dof))
    (q1, _), (q2, _) = (arm.ik(pose) for pose in milling_cell_poses())
    start, end = q1[RECOMMENDED_BRANCHES[0]], q2[RECOMMENDED_BRANCHES[1]]

    rows = []
    for nthread in (1, 0):
        checker = CollisionChecker(model, dof=arm.dof, nthread=nthread, backend="batch")
        checker.collides(q[:10])  # builds the batch
        label = f"batch, {checker._ensure_batch().nthread} thread(s)"
        seconds = _best(lambda c=checker: c.collides(q), args.repeats)
        rows.append((f"configurations/s  {label}", args.configs / seconds))
    checker = CollisionChecker(model, dof=arm.dof, backend="loop")
    seconds = _best(lambda: checker.collides_loop(q), args.repeats)
    rows.append(("configurations/s  Python loop (mj_kinematics + mj_collision)",
                 args.configs / seconds))
    (all1, _), (all2, _) = (arm.ik(pose) for pose in milling_cell_poses())
    for backend in ("batch", "loop"):
        checker = CollisionChecker(model, dof=arm.dof, backend=backend)
        n_samples = checker.path_samples(start, end).shape[0]
        seconds = _best(lambda c=checker: c.check_path(start, end), args.repeats)
        rows.append((f"path checks/s     1.1 -> 2.1 ({n_samples} samples), {backend}",
                     1.0 / seconds))
        seconds = _best(lambda c=checker: c.check_paths(all1[:, None], all2[None]), args.repeats)
        rows.append((f"path checks/s     all 64 transfers in one call, {backend}", 64 / seconds))

    print(f"CPUs: {os.cpu_count()}, configurations: {args.configs}, "
          f"resolution {checker.resolution * 1000:.0f} mm")
    width = max(len(name) for name, _ in rows)
    print(f"{'measure':<{width}}  {'rate':>10}")
    for name, rate in rows:
        print(f"{name:<{width}}  {rate:>10.0f}")


if __name__ == "__main__":
    main()
