"""Collision-check throughput: the compiled filter beside the exact Python backends.

    .venv/bin/python benchmarks/collision_throughput.py [--configs 20000] [--paths 300]
                                                        [--repeats 3]

Every row of one kind checks the same inputs, and the script asserts that every backend
returns the same answers before it times them (contact counts, verdicts, first colliding
samples). Backends: ``compiled`` (bounds, MuJoCo for what they cannot prove; verdict-only
calls stop at any contact, first-sample calls find the first), ``loop`` (the advancing
Python loop: the exact reference the compiled backend is tested equal to), ``batch``
(``mujoco.batch.Batch``, every grid sample) and an every-sample Python loop (the flat
checker: the plain δ-grid check, as a reference measured in the same run).

- Configurations: uniform in the anthropomorphic arm's joint limits, in the milling cell
  (the densest scene; about a third collide, and each of those MuJoCo must confirm).
- Paths: the paper's 1.1 → 2.1 transfer, all 64 milling transfers in one call, and
  ``--paths`` random-clutter paths of Anthropomorphic-v1's scene (from a free
  configuration by up to a quarter of every joint range).

The last table says how much of the grid the filter decided itself. Best of
``--repeats`` runs; numbers depend on the machine and its load.
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


def _every_sample_until_contact(checker: CollisionChecker, q0, q1) -> np.ndarray:
    """The flat δ-grid check: every grid sample in order, stopping at a path's first
    contact (the loop backend before conservative advancement)."""
    return np.array([
        checker._n_contacts_loop(checker.path_samples(a, b), stop_at_first=True).any()
        for a, b in zip(q0, q1, strict=True)
    ])


def _filter_share(checker: CollisionChecker, run) -> tuple[float, float]:
    """(bounded, MuJoCo-checked) samples per path of ``run`` (compiled backend)."""
    before = checker._filter.counters.copy()
    count = run()
    bounded, exact, _, _ = checker._filter.counters - before
    return bounded / count, exact / count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--paths", type=int, default=300)
    args = parser.parse_args()

    arm = make_arm("anthropomorphic")
    cell = build_model("anthropomorphic", "milling_cell")
    checkers = {name: CollisionChecker(cell, dof=arm.dof, backend=name)
                for name in ("compiled", "loop", "batch")}
    rng = np.random.default_rng(0)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    q = rng.uniform(lower, upper, size=(args.configs, arm.dof))
    counts = checkers["loop"].n_contacts(q)
    assert np.array_equal(checkers["compiled"].n_contacts(q), counts)
    assert np.array_equal(checkers["batch"].n_contacts(q), counts)
    free = q[counts == 0]
    rows: list[tuple[str, float]] = []
    label = f"configurations/s  milling cell, uniform ({(counts > 0).mean():.0%} collide)"
    for name in ("compiled", "loop", "batch"):
        checker = checkers[name]
        rows.append((f"{label}, {name}", len(q) / _best(lambda c=checker: c.collides(q),
                                                         args.repeats)))
    checker = checkers["compiled"]
    rows.append(("configurations/s  milling cell, the free ones only, compiled",
                 len(free) / _best(lambda: checker.collides(free), args.repeats)))

    (all1, _), (all2, _) = (arm.ik(pose) for pose in milling_cell_poses())
    start, end = all1[RECOMMENDED_BRANCHES[0]], all2[RECOMMENDED_BRANCHES[1]]
    n_samples = checker.path_samples(start, end).shape[0]
    reference = checkers["loop"].check_path(start, end)
    assert checker.check_path(start, end) == reference and not reference.collides
    one = f"path checks/s     1.1 -> 2.1 ({n_samples} samples)"
    rows.append((f"{one}, compiled (verdict)",
                 1 / _best(lambda: checker.paths_collide(start, end), args.repeats)))
    rows.append((f"{one}, compiled (first sample)",
                 1 / _best(lambda: checker.check_paths(start, end), args.repeats)))
    rows.append((f"{one}, loop", 1 / _best(lambda: checkers["loop"].check_path(start, end),
                                           args.repeats)))
    pairs = (all1[:, None], all2[None])
    expected = checkers["loop"].check_paths(*pairs)
    np.testing.assert_equal(checker.check_paths(*pairs), expected)
    assert np.array_equal(checker.paths_collide(*pairs), expected[0])
    many = "path checks/s     all 64 milling transfers in one call"
    rows.append((f"{many}, compiled (verdict)",
                 64 / _best(lambda: checker.paths_collide(*pairs), args.repeats)))
    rows.append((f"{many}, loop",
                 64 / _best(lambda: checkers["loop"].check_paths(*pairs), args.repeats)))

    clutter_rows, share = _clutter_paths(arm, args.paths, args.repeats)
    rows += clutter_rows
    print(f"CPUs: {os.cpu_count()}, resolution {checker.resolution * 1000:.0f} mm; every "
          "backend gave the same answers\n")
    width = max(len(name) for name, _ in rows)
    print(f"{'measure':<{width}}  {'rate':>10}")
    for name, rate in rows:
        print(f"{name:<{width}}  {rate:>10,.0f}")
    print()
    print("| path set | grid samples/path | bounded/path | MuJoCo checks/path |")
    print("|---|---:|---:|---:|")
    grid = n_samples
    bounded, exact = _filter_share(checker, lambda: (checker.paths_collide(start, end), 1)[1])
    print(f"| 1.1 -> 2.1 (verdict) | {grid} | {bounded:.1f} | {exact:.2f} |")
    for row in share:
        print(row)


def _clutter_paths(arm, count: int, repeats: int):
    model = build_model("anthropomorphic", "random_clutter")
    compiled = CollisionChecker(model, dof=arm.dof, backend="compiled")
    loop = CollisionChecker(model, dof=arm.dof, backend="loop")
    batch = CollisionChecker(model, dof=arm.dof, backend="batch")
    rng = np.random.default_rng(1)
    lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
    q0 = rng.uniform(lower, upper, size=(4 * count, arm.dof))
    q0 = q0[~loop.collides(q0)][:count]
    q1 = np.clip(q0 + rng.uniform(-0.25, 0.25, size=q0.shape) * (upper - lower), lower, upper)
    samples = int(loop.n_steps(q0, q1).sum() + len(q0))
    verdicts, first = loop.check_paths(q0, q1)
    assert np.array_equal(verdicts, batch.check_paths(q0, q1)[0])
    assert np.array_equal(verdicts, _every_sample_until_contact(loop, q0, q1))
    assert np.array_equal(verdicts, compiled.paths_collide(q0, q1))
    np.testing.assert_equal(compiled.check_paths(q0, q1), (verdicts, first))
    label = (f"path checks/s     random clutter ({len(q0)} paths, {samples} grid samples, "
             f"{verdicts.mean():.0%} hit)")
    rows = []
    for name, run in (
        ("compiled (verdict)", lambda: compiled.paths_collide(q0, q1)),
        ("compiled (first sample)", lambda: compiled.check_paths(q0, q1)),
        ("loop (advancing)", lambda: loop.check_paths(q0, q1)),
        ("every sample, loop (flat)", lambda: _every_sample_until_contact(loop, q0, q1)),
        ("batch (every sample)", lambda: batch.check_paths(q0, q1)),
    ):
        rows.append((f"{label}, {name}", len(q0) / _best(run, repeats)))
    grid = samples / len(q0)
    share = []
    for name, run in (("verdict", lambda: (compiled.paths_collide(q0, q1), len(q0))[1]),
                      ("first sample", lambda: (compiled.check_paths(q0, q1), len(q0))[1])):
        bounded, exact = _filter_share(compiled, run)
        share.append(f"| random clutter ({name}) | {grid:.0f} | {bounded:.1f} | {exact:.2f} |")
    return rows, share


if __name__ == "__main__":
    main()
