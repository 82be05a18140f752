"""Interval estimates over a sweep: ``python -m train.aggregate [--root runs/sweep]``.

Per env id and policy, from every trial's ``evaluation.json`` and the id's baselines
(``train.sweep``), following Agarwal et al. (NeurIPS 2021) with rliable:

- **Normalised score** per held-out task: (R − R_random) / (R_oracle − R_random), so the
  DP oracle scores 1 and the uniform random policy 0 on every task (both play the same
  tasks and scenes as everyone). Tasks on which random already attains the optimum carry
  no information and are left out (counted in the record); an id where that is every task
  (one branch) gets no score. Reported: the **IQM** over runs × tasks with its 95 %
  stratified-bootstrap CI.
- **Gaps** to the oracle: the **IQM gap** (``gap``), the IQM over runs × tasks of the
  per-task (R_oracle − R)/|R_oracle| (tasks where the oracle returns 0 left out), with its
  CI; the **mean gap** (``mean_gap``),
  (mean R_oracle − mean R)/|mean R_oracle| over the same runs × tasks, a point value.
- **Success rate** with a stratified-bootstrap 95 % CI.
- **Probability of improvement** of each learned policy over ``paper_rule`` and over
  ``receding_dp`` on the normalised scores, with its CI; and per policy the fraction of
  informative runs × tasks on which it attains the optimum (``optimal``): a rival optimal
  on a fraction f of the tasks can be beaten with probability at most 1 − f/2.
- **Learning curves**: held-out return during training, mean over each round's tasks,
  the IQM across seeds with a bootstrap band.

Every interval resamples the tasks as well as the runs within them (rliable's
``task_bootstrap``): the held-out tasks are a sample of the task distribution. Analytic
baselines are deterministic (the random one is seeded), so they are one run and their
intervals come from the tasks alone. ``decision_ms`` is the mean wall time per decision.

The statistics are computed here and handed to ``train.publish`` (``--publish``), which
writes and renders them and imports nothing of this module.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ikbranch_gym.agents import DPOracle, PaperRule, RandomBranch, RecedingDP
from ikbranch_gym.agents.evaluation import iqm_rows, mean_gap, task_gaps
from ikbranch_gym.train.sweep import env_name

#: Bootstrap resamples for every interval.
REPS = 2000
#: Two-sided interval coverage, and its tails as arch computes them (rliable's default).
SIZE = 0.95
_TAILS = [100 * ((1.0 - SIZE) / 2), 100 * (1.0 - (1.0 - SIZE) / 2)]
#: Resamples evaluated in one batch (bounds the memory of a pairwise comparison).
_BATCH = 250
ORACLE, RANDOM = DPOracle.name, RandomBranch.name
#: What learned policies are compared with (probability of improvement).
RIVALS = (PaperRule.name, RecedingDP.name)

#: A statistic of a batch of bootstrap resamples: (R, runs, tasks) → (R,), or for a
#: comparison two batches (R, runs_x, tasks), (R, runs_y, tasks) → (R,).
Statistic = Callable[..., np.ndarray]


def _estimate(scores: np.ndarray | tuple[np.ndarray, np.ndarray], statistic: Statistic,
              seed: int = 0) -> tuple[float, float, float]:
    """(point, low, high) of ``statistic`` on ``scores`` (runs, tasks), or on a pair of
    them (a comparison), with the 95 % percentile interval of rliable's stratified
    bootstrap: one array resampled over runs within each task and over tasks
    (``task_bootstrap``: the held-out tasks are a sample of the task distribution, not a
    fixed benchmark suite), a pair each over its runs within each task (rliable's
    ``StratifiedIndependentBootstrap``, which takes no task resampling).

    It is ``rliable.library.get_interval_estimates(…, reps=REPS, task_bootstrap=True)``
    to the bit (tested), computed in batches: the same resampling indices, drawn by the
    same calls in the same order from numpy's *global* generator (which rliable uses
    whatever its ``random_state`` says: it is seeded with ``seed`` for the call and put
    back after, so the same scores give the same interval), the statistic evaluated on
    many resamples at once, and arch's percentiles, where rliable goes through arch's
    bootstrap iterator one resample at a time."""
    pair = isinstance(scores, tuple)
    arrays = tuple(np.asarray(a, dtype=float) for a in (scores if pair else (scores,)))
    if any(a.ndim != 2 or a.size == 0 for a in arrays) or len({a.shape[1] for a in arrays}) != 1:
        raise ValueError("bootstrap scores must be non-empty (runs, tasks) arrays over the "
                         f"same tasks, got shapes {[a.shape for a in arrays]}")
    tasks = arrays[0].shape[1]
    strata = np.arange(tasks)[None]
    outer = np.random.get_state()  # noqa: NPY002 (the legacy global one, on purpose)
    np.random.seed(seed)  # noqa: NPY002
    try:
        draws: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in arrays]
        for _ in range(REPS):
            for a, drawn in zip(arrays, draws, strict=True):
                runs = _choice(len(a), a.shape)
                drawn.append((runs, strata if pair else _choice(tasks, (1, tasks))))
    finally:
        np.random.set_state(outer)  # noqa: NPY002
    values = np.empty(REPS)
    for begin in range(0, REPS, _BATCH):
        batch = [a[np.stack([runs for runs, _ in drawn[begin:begin + _BATCH]]),
                   np.stack([task for _, task in drawn[begin:begin + _BATCH]])]
                 for a, drawn in zip(arrays, draws, strict=True)]
        values[begin:begin + _BATCH] = statistic(*batch)
    low, high = np.percentile(values, _TAILS)
    return float(statistic(*(a[None] for a in arrays))[0]), float(low), float(high)


def _choice(n: int, shape: tuple[int, ...]) -> np.ndarray:
    """rliable's ``np.random.choice(n, shape, replace=True)``, the same draws for half the
    call's overhead: the legacy generator's ``choice`` is ``randint(0, n, shape)``, and a
    range of one value is all zeros and draws nothing."""
    if n == 1:
        return np.zeros(shape, dtype=np.int64)
    return np.random.randint(0, n, shape)  # noqa: NPY002


def mean_of_task_means(samples: np.ndarray) -> np.ndarray:
    """(R,) rliable's ``metrics.aggregate_mean`` (the mean over tasks of the mean over
    runs) of each of ``samples`` (R, runs, tasks), the same reductions in the same order."""
    return samples.mean(axis=1).mean(axis=1)


def load(root: Path) -> dict[str, dict[str, Any]]:
    """env id -> {"baselines": record, "trials": {algo: [records by seed]}}."""
    out: dict[str, dict[str, Any]] = {}
    for path in sorted((root / "baselines").glob("*.json")):
        record = json.loads(path.read_text())
        out.setdefault(record["env"], {"trials": {}})["baselines"] = record
    for path in sorted((root / "runs").glob("*/*/seed*/evaluation.json")):
        record = json.loads(path.read_text())
        entry = out.setdefault(record["env"], {"trials": {}})
        entry["trials"].setdefault(record["algo"], []).append(record)
    for entry in out.values():
        for records in entry["trials"].values():
            records.sort(key=lambda r: r["seed"])
    return out


def _curves(root: Path, env_id: str, algo: str, seeds: list[int]) -> dict[str, Any] | None:
    """The IQM learning curve over the seeds' evaluation logs, at the timesteps every log
    has (matched by timestep: a log that lacks one, as a shorter run does, leaves it
    out); None where there is no log or no timestep all of them share."""
    rows = []
    for seed in seeds:
        path = root / "runs" / env_name(env_id) / algo / f"seed{seed}" / "evaluations.npz"
        if path.exists():
            with np.load(path) as log:
                rows.append(dict(zip(log["timesteps"].tolist(),
                                     log["results"].mean(axis=1).tolist(), strict=True)))
    if not rows:
        return None
    steps = sorted(set.intersection(*(set(row) for row in rows)))
    if not steps:
        return None
    returns = np.array([[row[step] for step in steps] for row in rows])
    estimates = [_estimate(returns[:, [i]], iqm_rows) for i in range(len(steps))]
    return {"timesteps": steps, "iqm": [e[0] for e in estimates],
            "low": [e[1] for e in estimates], "high": [e[2] for e in estimates]}


#: Scores closer than this are the same outcome (a tie): the same moves priced by code that
#: rounds differently (a policy evaluated before an IK change, its rival after) differ
#: in the last bits, ~1e-15; different moves differ by far more.
SCORE_TIE = 1e-9


def probability_of_improvement(scores_x: np.ndarray, scores_y: np.ndarray) -> float:
    """rliable's ``metrics.probability_of_improvement`` (P(X_m > Y_m), ties counting
    half, averaged over tasks m), vectorised: rliable calls scipy's Mann-Whitney U once
    per task, about 1 ms each, which inside a 2,000-sample bootstrap over 200 tasks took
    minutes per policy pair. Mann-Whitney's U is exactly the count of pairs x > y plus
    half the ties, so the values are the same (tested equal), but for one deliberate
    difference: scores within ``SCORE_TIE`` tie, where rliable's exact comparison would
    let rounding decide."""
    return float(improvement_rows(np.asarray(scores_x)[None], np.asarray(scores_y)[None])[0])


def improvement_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(R,) :func:`probability_of_improvement` of each pair of resamples ``x`` (R, runs_x,
    tasks) and ``y`` (R, runs_y, tasks)."""
    difference = x[:, :, None, :] - y[:, None, :, :]
    greater = (difference > SCORE_TIE).sum(axis=(1, 2))
    ties = (np.abs(difference) <= SCORE_TIE).sum(axis=(1, 2))
    per_task = (greater + 0.5 * ties) / (x.shape[1] * y.shape[1])
    return per_task.mean(axis=1)


def summarise(root: Path, env_id: str, entry: dict[str, Any]) -> dict[str, Any]:
    """The aggregate record of one env id."""
    baselines = entry["baselines"]["policies"]
    oracle, random = np.array(baselines[ORACLE]["returns"]), np.array(baselines[RANDOM]["returns"])
    span = oracle - random
    informative = np.abs(span) > 1e-9 * np.maximum(1.0, np.abs(oracle))
    runs: dict[str, dict[str, np.ndarray]] = {}
    for name, metrics_ in baselines.items():
        runs[name] = {"returns": np.array([metrics_["returns"]]),
                      "successes": np.array([metrics_["successes"]], dtype=float),
                      "decision_ms": np.array([metrics_["decision_ms"]])}
    seeds, budgets = {}, {}
    for algo, records in entry["trials"].items():
        for record in records:
            if record["policy"]["returns"] and len(record["policy"]["returns"]) != len(oracle):
                raise ValueError(f"{env_id} {algo} seed {record['seed']}: other task count")
            if not np.allclose(record["oracle"]["returns"], oracle, rtol=0, atol=1e-9):
                raise ValueError(f"{env_id} {algo} seed {record['seed']}: other tasks")
        runs[algo] = {
            "returns": np.array([r["policy"]["returns"] for r in records]),
            "successes": np.array([r["policy"]["successes"] for r in records], dtype=float),
            "decision_ms": np.array([r["policy"]["decision_ms"] for r in records]),
        }
        seeds[algo] = [r["seed"] for r in records]
        budgets[algo] = {"timesteps": sorted({int(r["timesteps"]) for r in records}),
                         "train_minutes": float(np.mean([r["train_minutes"] for r in records]))}
        cloned = sorted({int(r["imitation_episodes"]) for r in records
                         if "imitation_episodes" in r})
        if cloned:
            budgets[algo]["imitation_episodes"] = cloned
    result: dict[str, Any] = {"env": env_id, "episodes": len(oracle),
                              "task_seed": entry["baselines"]["task_seed"],
                              "env_kwargs": entry["baselines"]["env_kwargs"],
                              "informative_tasks": int(informative.sum()), "policies": {}}
    for name, run in runs.items():
        returns = run["returns"]
        row: dict[str, Any] = {
            "runs": len(returns), "seeds": seeds.get(name),
            "success": _estimate(run["successes"], mean_of_task_means),
            # The IQM gap over the tasks the oracle's return gives a scale (as in the
            # evaluation table).
            "gap": (_estimate(task_gaps(returns, oracle), iqm_rows)
                    if (oracle != 0.0).any() else None),
            "mean_gap": mean_gap(returns, oracle),
            "mean_return": float(returns.mean()),
            "decision_ms": float(run["decision_ms"].mean())}
        if informative.any():
            score = (returns[:, informative] - random[informative]) / span[informative]
            row["score"] = _estimate(score, iqm_rows)
            # How often the policy attains the optimum (score 1 up to rounding): where a
            # rival always does, no policy can beat it (P(improvement) at most 0.5).
            row["optimal"] = float(np.mean(score >= 1.0 - 1e-9))
            run["score"] = score
        row.update(budgets.get(name, {}))
        result["policies"][name] = row
    for algo in entry["trials"]:
        row = result["policies"][algo]
        if "score" not in runs[algo]:
            continue
        row["improvement"] = {
            rival: _estimate((runs[algo]["score"], runs[rival]["score"]), improvement_rows)
            for rival in RIVALS if "score" in runs[rival]
        }
        row["learning_curve"] = _curves(root, env_id, algo, seeds[algo])
        # The committed model: the seed whose mean score is nearest the row's IQM.
        per_run = runs[algo]["score"].mean(axis=1)
        row["representative_seed"] = int(seeds[algo][int(np.argmin(np.abs(
            per_run - row["score"][0])))])
    return result


def aggregate(root: Path) -> dict[str, dict[str, Any]]:
    """Every env id of the sweep under ``root`` that has its baselines."""
    return {env_id: summarise(root, env_id, entry)
            for env_id, entry in sorted(load(root).items()) if "baselines" in entry}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m train.aggregate", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", type=Path, default=Path("runs") / "sweep")
    parser.add_argument("--out", type=Path, help="write the aggregate as JSON here")
    parser.add_argument("--publish", action="store_true",
                        help="archive the root's finished trials in docs/results/sweep/trials, "
                             "(trials of a raised budget staged until they cover the row's "
                             "seeds), aggregate the archive, copy the representative models into "
                             "models/, plot, and render docs/results.md and the README's "
                             "results table (train/publish.py)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if args.publish:
        from ikbranch_gym.train.publish import SWEEP_RESULTS, archive, carry_over
        from ikbranch_gym.train.sweep import ARCHIVE

        path = SWEEP_RESULTS / "aggregate.json"
        published = json.loads(path.read_text()) if path.exists() else {}
        left_out: list[tuple[Path, int, int]] = []
        archive(args.root, published=published, left_out=left_out)
        for directory, steps, row_steps in left_out:
            print(f"left out {directory}: {steps:,} steps, where its row has {row_steps:,}")
        records = carry_over(aggregate(ARCHIVE), published)
    else:
        records = aggregate(args.root)
    for env_id, record in records.items():
        print(f"\n{env_id} ({record['episodes']} held-out tasks)")
        for name, row in record["policies"].items():
            score = row.get("score")
            text = "n/a" if score is None else f"{score[0]:.3f} [{score[1]:.3f}, {score[2]:.3f}]"
            success = row["success"]
            print(f"  {name:<14} runs {row['runs']}  score IQM {text}  success "
                  f"{success[0]:.0%} [{success[1]:.0%}, {success[2]:.0%}]")
    if args.out:
        args.out.write_text(json.dumps(records, indent=1) + "\n")
    if args.publish:
        from ikbranch_gym.train.publish import prune_staged, publish, write_readme, write_results

        written = publish(args.root, records)
        prune_staged()
        print(f"published {len(written)} files; {write_results()}; {write_readme(records)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
