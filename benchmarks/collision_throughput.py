"""Collision-check throughput: the compiled filter beside the exact Python backends and
beside MuJoCo itself.

    .venv/bin/python benchmarks/collision_throughput.py [--configs 20000] [--paths 300]
        [--repeats 3] [--env-paths 500] [--ids IKBranch/UR5e-v0 ...]

Every row of one kind checks the same inputs, and the script asserts that every backend
returns the same answers before it times them (contact counts, verdicts, first colliding
samples). Backends: ``compiled`` (the filter: three deciders per sample — bounds prove it
free, inner shapes, "witnesses", prove it in contact, and ``mj_kinematics`` +
``mj_collision`` decide only where neither proof holds; verdict-only calls stop at any
contact, first-sample calls find the first), ``loop`` (the advancing Python loop: the
exact reference the compiled backend is tested equal to), ``batch``
(``mujoco.batch.Batch``, every grid sample) and an every-sample Python loop (the flat
checker: the plain δ-grid check, as a reference measured in the same run).

- Configurations: uniform in the anthropomorphic arm's joint limits, in the milling cell
  (the densest scene; about a third collide, and witnesses prove those contacts, MuJoCo
  deciding only what neither bounds nor witnesses can).
- Paths: the paper's 1.1 → 2.1 transfer, all 64 milling transfers in one call, and
  ``--paths`` random-clutter paths of Anthropomorphic-v1's scene (from a free
  configuration by up to a quarter of every joint range).

The share table says who decided the grid samples: bounded samples are those the filter
visited (the rest of the grid its bounds cleared without a visit), of which the witnessed
ones its inner shapes proved in contact and the MuJoCo checks went to ``mj_collision``.

The last table times the filter beside MuJoCo on the same model in the same run, per env
id of ``--ids`` (its scene after ``reset(seed=0)``, which lays a clutter; the checker's
margined model, which the filter reads): ``--configs`` uniform configurations through
``CompiledFilter.collide`` (asserted equal to MuJoCo's ncon > 0 on every one), and
``--env-paths`` verdict-only clutter paths through ``rows_paths_collide`` (per bounded
sample with the scalar kernel alone, and per path with and without the lanes, which bound
16 samples a call: ``envs/models/filter/lanes.py``; the verdicts asserted equal; and the
lane kernel alone, ns per lane of a call from a numba loop on 16 of these paths' middle
samples), against
``mj_kinematics`` + ``mj_collision`` per configuration on a fresh
``MjData``, called from a Python loop (``data.qpos[:dof] = q``, reading ``ncon``) and from
a tight loop (qpos through a preallocated view, nothing read), and from a numba loop that
calls the two C functions as the filter's own MuJoCo fallback does (no Python per
configuration: the MuJoCo column); the loop that only sets qpos shows the Python part of
the tight loop. Best of ``--repeats`` runs; numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import gymnasium as gym
import mujoco
import numba
import numpy as np

import ikbranch_gym.envs  # noqa: F401  (registers the env ids)
from ikbranch_gym.envs.kinematics import make_arm
from ikbranch_gym.envs.models import (
    RECOMMENDED_BRANCHES,
    CollisionChecker,
    build_model,
    milling_cell_poses,
    native,
)
from ikbranch_gym.envs.models.filter import COUNTERS
from ikbranch_gym.envs.models.filter.kernels import (
    LANE_FUNCTION,
    LANE_WORK,
    _call_lanes,
    _exact_contacts,
    _lane_block,
)
from ikbranch_gym.envs.models.filter.lanes import LANES

#: The env ids of the last table (``--ids``): their scenes after ``reset(seed=0)``.
ENV_IDS = ("IKBranch/Anthropomorphic-v2", "IKBranch/KukaKR6-v0", "IKBranch/UR5e-v0",
           "IKBranch/Cartesian-v2", "IKBranch/ToolTransfer-v1")


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


def _filter_share(checker: CollisionChecker, run) -> tuple[float, float, float]:
    """(bounded, witnessed, MuJoCo-checked) samples per path of ``run`` (compiled backend;
    ``run`` returns its number of paths)."""
    before = checker._filter.counters.copy()
    count = run()
    spent = dict(zip(COUNTERS, checker._filter.counters - before, strict=True))
    return spent["bounded"] / count, spent["witnessed"] / count, spent["mujoco"] / count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--paths", type=int, default=300)
    parser.add_argument("--env-paths", type=int, default=500,
                        help="clutter paths per env id of the last table")
    parser.add_argument("--ids", nargs="*", default=list(ENV_IDS), metavar="ID",
                        help="env ids of the last table (none: skip it)")
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
    print("| path set | grid samples/path | bounded samples/path | witnessed/path "
          "| MuJoCo checks/path |")
    print("|---|---:|---:|---:|---:|")
    grid = n_samples
    bounded, witnessed, exact = _filter_share(
        checker, lambda: (checker.paths_collide(start, end), 1)[1])
    print(f"| 1.1 -> 2.1 (verdict) | {grid} | {bounded:.1f} | {witnessed:.2f} | {exact:.2f} |")
    for row in share:
        print(row)
    if args.ids:
        _beside_mujoco(args.ids, args.configs, args.env_paths, args.repeats)


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
        bounded, witnessed, exact = _filter_share(compiled, run)
        share.append(f"| random clutter ({name}) | {grid:.0f} | {bounded:.1f} "
                     f"| {witnessed:.2f} | {exact:.2f} |")
    return rows, share


@numba.njit
def _native_loop(rows, qpos0, exact, out):
    """``out[i]``: MuJoCo's contact count at ``rows[i]`` (leading qpos entries, the rest at
    ``qpos0``), ``mj_kinematics`` + ``mj_collision`` called from compiled code as the
    filter calls them (``exact``: ``native.exact_addresses``)."""
    qpos = qpos0.copy()
    for i in range(rows.shape[0]):
        qpos[: rows.shape[1]] = rows[i]
        out[i] = _exact_contacts(qpos, exact)


def _mujoco_loops(model: mujoco.MjModel, q: np.ndarray, repeats: int):
    """MuJoCo's verdicts (ncon > 0) at configurations ``q`` (M, dof) on a fresh ``MjData``,
    and the seconds per configuration of: the Python loop (``data.qpos[:dof] = q``,
    ``mj_kinematics`` + ``mj_collision``, ``ncon`` read), the tight loop (qpos through a
    preallocated view, nothing read), the tight loop's qpos writes alone, and the two
    calls from compiled code (:func:`_native_loop`: no Python per configuration)."""
    data = mujoco.MjData(model)
    dof = q.shape[1]
    ncon = np.empty(len(q), dtype=np.int64)

    def plain():
        for i in range(len(q)):
            data.qpos[:dof] = q[i]
            mujoco.mj_kinematics(model, data)
            mujoco.mj_collision(model, data)
            ncon[i] = data.ncon

    qpos, kinematics, collision = data.qpos[:dof], mujoco.mj_kinematics, mujoco.mj_collision

    def tight():
        for row in q:
            qpos[:] = row
            kinematics(model, data)
            collision(model, data)

    def writes():
        for row in q:
            qpos[:] = row

    exact, counts = native.exact_addresses(model, data), np.empty(len(q), dtype=np.int64)

    def compiled():
        _native_loop(q, model.qpos0, exact, counts)

    times = [_best(run, repeats) / len(q) for run in (plain, tight, writes, compiled)]
    assert np.array_equal(counts, ncon), "MuJoCo from compiled code != from Python"
    return ncon > 0, times


def _beside_mujoco(ids, configs: int, count: int, repeats: int) -> None:
    """The filter and MuJoCo on each env's scene after ``reset(seed=0)``, same run."""
    print("\nns per sample beside MuJoCo on the same model, same run "
          f"({configs} configurations, ~{count} clutter paths per id; MuJoCo = "
          "mj_kinematics + mj_collision on a fresh MjData)\n")
    print("| id | slots | pairs | ns/configuration (filter) | in contact % | witnessed % "
          "| MuJoCo calls % | ns/bounded path sample (scalar kernel alone) "
          "| bounded samples/path | paths hit % | µs/path, scalar kernel alone "
          "| µs/path, with lanes | lane samples/path | scalar samples/path, with lanes "
          "| ns/lane, the lane kernel alone "
          "| ns/configuration MuJoCo (kinematics+collision, numba loop) "
          "| ns MuJoCo, Python loop | ns MuJoCo, tight Python loop | ns its qpos writes alone |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:"
          "|---:|---:|")
    for env_id in ids:
        env = gym.make(env_id)
        env.reset(seed=0)
        arm, checker = env.unwrapped.arm, env.unwrapped.checker
        filt, model = checker._filter, checker.model
        rng = np.random.default_rng(2)
        lower, upper = arm.joint_limits[:, 0], arm.joint_limits[:, 1]
        q = np.ascontiguousarray(rng.uniform(lower, upper, size=(configs, arm.dof)))

        # (a) configurations, as the env checks them
        before = filt.counters.copy()
        verdicts = filt.collide(q) > 0
        spent = dict(zip(COUNTERS, filt.counters - before, strict=True))
        per_config = _best(lambda f=filt, q=q: f.collide(q), repeats) / configs
        reference, (plain, tight, writes, native_call) = _mujoco_loops(model, q, repeats)
        assert np.array_equal(verdicts, reference), f"{env_id}: filter != MuJoCo"

        # (b) verdict-only paths from free configurations (as _clutter_paths draws them)
        starts = rng.uniform(lower, upper, size=(4 * count, arm.dof))
        q0 = np.ascontiguousarray(starts[~checker.rows_collide(starts)][:count])
        q1 = np.ascontiguousarray(np.clip(
            q0 + rng.uniform(-0.25, 0.25, size=q0.shape) * (upper - lower), lower, upper))
        run = lambda c=checker, q0=q0, q1=q1: c.rows_paths_collide(q0, q1)  # noqa: E731
        lanes = int(filt._exact[0, LANE_FUNCTION])
        filt._exact[0, LANE_FUNCTION] = 0  # the scalar kernel alone first
        before = filt.counters.copy()
        hits = run()
        bounded = int((filt.counters - before)[COUNTERS.index("bounded")])
        per_path = _best(run, repeats) / len(q0)
        filt._exact[0, LANE_FUNCTION] = lanes
        before = filt.counters.copy()
        assert np.array_equal(run(), hits), f"{env_id}: lanes changed a verdict"
        with_lanes = dict(zip(COUNTERS, filt.counters - before, strict=True))
        per_path_lanes = _best(run, repeats) / len(q0) if lanes else math.nan
        per_lane = _lane_call(filt, q0, q1, repeats) if lanes else math.nan
        env.close()

        slots, pairs = len(filt.scene.slot_geom), len(filt.scene.pair_a)
        print(f"| {env_id} | {slots} | {pairs} | {per_config * 1e9:,.0f} "
              f"| {verdicts.mean():.1%} "
              f"| {(spent['witnessed'] + spent['lane contacts']) / configs:.2%} "
              f"| {spent['mujoco'] / configs:.2%} | {per_path * 1e9 / bounded * len(q0):,.0f} "
              f"| {bounded / len(q0):.1f} | {hits.mean():.0%} | {per_path * 1e6:.1f} "
              f"| {per_path_lanes * 1e6:.1f} | {with_lanes['lane samples'] / len(q0):.1f} "
              f"| {with_lanes['bounded'] / len(q0):.1f} | {per_lane * 1e9:,.0f} "
              f"| {native_call * 1e9:,.0f} "
              f"| {plain * 1e9:,.0f} | {tight * 1e9:,.0f} | {writes * 1e9:,.0f} |")


@numba.njit
def _lane_loop(exact, block, counters, calls):
    for _ in range(calls):
        _call_lanes(exact, block, LANES, counters)


def _lane_call(filt, q0: np.ndarray, q1: np.ndarray, repeats: int) -> float:
    """Seconds per lane of the lane kernel alone: 16 samples, each in the middle of one of
    these paths with a step of 1/64 of it asked, bounded again and again by a numba loop
    of calls (no Python per call), best of ``repeats`` runs of 2,000 calls."""
    scene, exact = filt.scene, filt._exact[0]
    dof = q0.shape[1]
    arrays, block = _lane_block(scene.qpos0, len(scene.pair_a), int(exact[LANE_WORK]))
    arrays[0][:dof] = q0[:LANES].T
    arrays[1][:dof] = (q1[:LANES] - q0[:LANES]).T
    arrays[2][:], arrays[3][:] = 0.5, 1.0 / 64
    arrays[4][:] = (np.abs(q1[:LANES] - q0[:LANES]) @ scene.pair_lever[0][:dof]).T
    counters = np.zeros(len(COUNTERS), dtype=np.int64)
    _lane_loop(exact, block, counters, 1)
    return _best(lambda: _lane_loop(exact, block, counters, 2000), repeats) / (2000 * LANES)


if __name__ == "__main__":
    main()
