"""IK throughput per arm: poses/s on batches of 100k, cost per returned solution, and
single-pose latency.

    python benchmarks/ik_throughput.py [--batch 100000] [--repeats 5] [--arm NAME ...]

Prints a Markdown table (best of ``--repeats``; the machines are shared and noisy). Batches
and single poses go through the same compiled driver (``envs/kinematics/compiled.py``), one
core. The first IK call of the process is timed apart and printed below the table: it
loads the compiled driver from numba's on-disk cache, or compiles it (about 7 s) when the
cache is cold.

Columns: K branches (closed-form × turn windows); valid branches per pose on poses of
random configurations inside the limits; batched poses/s; ns per returned (valid)
solution; single-pose latency of ``arm.ik(pose)`` for one (4, 4) pose.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from ikbranch_gym.envs.kinematics import ARM_NAMES, make_arm  # noqa: E402
from ikbranch_gym.envs.kinematics.compiled import compiled_solve_poses  # noqa: E402


def best_time(function, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--single-calls", type=int, default=2000)
    parser.add_argument("--arm", action="append", choices=ARM_NAMES,
                        help="arms to measure (default: all)")
    args = parser.parse_args()

    rng = np.random.default_rng(0)
    start = time.perf_counter()
    first = make_arm("cartesian")
    first.ik(first.fk(first.home))
    first_call = time.perf_counter() - start
    print(f"| arm | K | valid / pose | batch poses/s ({args.batch:,}) | ns / solution | "
          "single pose (µs) |")
    print("|---|---:|---:|---:|---:|---:|")
    for name in args.arm or ARM_NAMES:
        arm = make_arm(name)
        q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (args.batch, arm.dof))
        poses = arm.fk(q)
        _, valid = arm.ik(poses)
        batch_seconds = best_time(lambda poses=poses, arm=arm: arm.ik(poses), args.repeats)
        singles = poses[: args.single_calls]

        def single_calls(arm=arm, singles=singles):
            for pose in singles:
                arm.ik(pose)

        single_seconds = best_time(single_calls, args.repeats) / len(singles)
        per_pose = valid.sum() / args.batch
        print(
            f"| {name} | {arm.n_branches} | {per_pose:.1f} | {args.batch / batch_seconds:,.0f} | "
            f"{batch_seconds / valid.sum() * 1e9:.0f} | {single_seconds * 1e6:.1f} |"
        )
    stats = compiled_solve_poses().stats
    source = "loaded from the on-disk cache" if sum(stats.cache_hits.values()) else "compiled"
    print()
    print(f"First IK call of the process: {first_call:.2f} s (numba import and the driver "
          f"{source}; once per process, every arm)")

if __name__ == "__main__":
    main()
