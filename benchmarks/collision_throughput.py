"""Collision-check throughput: batched (mujoco.batch) vs a plain Python loop, and path checks.

    .venv/bin/python benchmarks/collision_throughput.py [--configs 20000] [--repeats 3]

Configurations are uniform in the anthropomorphic arm's joint limits, in the milling cell
(the densest scene). The path is the paper's 1.1 → 2.1 transfer at the default resolution.
The last rows check ``--paths`` random paths in Anthropomorphic-v1's random clutter (from
a free configuration by up to a quarter of every joint range) three ways: every grid
sample in a plain loop stopping at the first contact (the loop backend before
conservative advancement), the batch backend, and the loop backend (advancing); all three
give the same verdicts. Best of ``--repeats`` runs; numbers depend on the machine and its
load.
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
    parser.add_argument("--paths", type=int, default=300)
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

    rows += _clutter_paths(arm, args.paths, args.repeats)
    print(f"CPUs: {os.cpu_count()}, configurations: {args.configs}, "
          f"resolution {checker.resolution * 1000:.0f} mm")
    width = max(len(name) for name, _ in rows)
    print(f"{'measure':<{width}}  {'rate':>10}")
    for name, rate in rows:
        print(f"{name:<{width}}  {rate:>10.0f}")


def _every_sample_until_contact(checker: CollisionChecker, q0, q1) -> np.ndarray:
    """The loop backend before conservative advancement: every grid sample in order."""
    return np.array([
        checker._n_contacts_loop(checker.path_samples(a, b), stop_at_first=True).any()
        for a, b in zip(q0, q1, strict=True)
    ])


def _clutter_paths(arm, count: int, repeats: int) -> list[tuple[str, float]]:
    model = build_model("anthropomorphic", "random_clutter")
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    batch = CollisionChecker(model, dof=arm.dof, backend="batch")
    rng = np.random.default_rng(1)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    q0 = rng.uniform(lower, upper, size=(4 * count, arm.dof))
    q0 = q0[~loop.collides(q0)][:count]
    q1 = np.clip(q0 + rng.uniform(-0.25, 0.25, size=q0.shape) * (upper - lower), lower, upper)
    samples = int(loop.n_steps(q0, q1).sum() + len(q0))
    verdicts = loop.check_paths(q0, q1)[0]
    assert np.array_equal(verdicts, batch.check_paths(q0, q1)[0])
    assert np.array_equal(verdicts, _every_sample_until_contact(loop, q0, q1))
    label = f"random-clutter paths ({len(q0)}, {samples} grid samples, {verdicts.mean():.0%} hit)"
    rows = []
    for name, run in (
        ("every sample, loop", lambda: _every_sample_until_contact(loop, q0, q1)),
        ("batch", lambda: batch.check_paths(q0, q1)),
        ("loop (advancing)", lambda: loop.check_paths(q0, q1)),
    ):
        rows.append((f"path checks/s     {label}, {name}", len(q0) / _best(run, repeats)))
    return rows


if __name__ == "__main__":
    main()
