"""IK throughput per arm: poses/s on batches of 100k and single-pose latency.

    python benchmarks/ik_throughput.py [--batch 100000] [--repeats 5]

Prints a Markdown table (best of ``--repeats``; the machines are shared and noisy). Run it
single-threaded for the per-core figure: numpy's element-wise kernels are single-threaded,
and OMP/OPENBLAS threads are pinned to 1 below for the small matrix products.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from envs.kinematics import ARM_NAMES, make_arm  # noqa: E402


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
    args = parser.parse_args()

    rng = np.random.default_rng(0)
    print(f"| arm | K | batch poses/s ({args.batch:,}) | single-pose latency (µs) |")
    print("|---|---:|---:|---:|")
    for name in ARM_NAMES:
        arm = make_arm(name)
        q = rng.uniform(arm.joint_limits[:, 0], arm.joint_limits[:, 1], (args.batch, arm.dof))
        poses = arm.fk(q)
        batch_seconds = best_time(lambda poses=poses, arm=arm: arm.ik(poses), args.repeats)
        single = poses[0]

        def single_calls(arm=arm, single=single):
            for _ in range(args.single_calls):
                arm.ik(single)

        single_seconds = best_time(single_calls, args.repeats) / args.single_calls
        print(
            f"| {name} | {arm.n_branches} | {args.batch / batch_seconds:,.0f} | "
            f"{single_seconds * 1e6:.1f} |"
        )


if __name__ == "__main__":
    main()
