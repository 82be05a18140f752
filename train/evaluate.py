"""Compare policies on the same tasks: ``python -m train.evaluate``.

    python -m train.evaluate --env IKBranch/ToolTransfer-v2 --policy paper_rule \\
        --policy receding_dp --policy runs/ppo.zip --episodes 50 \\
        --json results.json --plot results.png

``--policy`` is repeatable: a baseline name (``paper_rule``, ``paper_pair_rule``,
``dp_oracle``, ``receding_dp[:H]``, ``random[:SEED]``, ``fixed[:BRANCH]``), an SB3 model
zip (PPO or MaskablePPO, recognised from the file), its actor exported by ``ikbranch
export`` (``.npz``), or ``MODULE:ATTR`` (``MODULE`` a module
importable from here or the working directory, or a ``.py`` file): ``ATTR`` is a callable
``policy(obs, mask) -> action`` (``mask`` the (K,) bool array of the branches allowed), a
factory of one (a class, or a function called with no argument), or an SB3 model object.
``--wrapper MODULE:ATTR`` (repeatable, applied in order) wraps every evaluated env in a
Gymnasium wrapper class or a callable ``env -> env``: a policy trained under a wrapper is
evaluated under it. Every policy plays the same wrapped env and chooses among the branches
its outermost wrapper allows (``action_masks()`` through the wrappers, narrowed by
``info["action_mask"]``).

The DP oracle always runs: the gaps are measured against it on the same tasks. ``mean
gap`` = (mean R_oracle − mean R) / |mean R_oracle| over the evaluated tasks; ``IQM gap`` =
the interquartile mean over tasks of (R_oracle,i − R_i) / |R_oracle,i| (tasks where the
oracle's return is 0 are left out, and the table says how many). Episode e of every policy
uses task seed S + e; S defaults to ``envs.seeds.TEST_SEED``, beyond every training run's
tasks, and an id that draws a clutter per episode plays held-out scenes
(``HELD_OUT_SCENES``) unless ``--env-kwargs`` sets ``scene_seeds``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from ikbranch_gym.agents.evaluation import evaluate, resolve, with_gaps
from ikbranch_gym.envs.seeds import TEST_SEED, held_out

COLUMNS = (
    ("policy", "{}"),
    ("success", "{:.0%}"),
    ("return", "{}"),
    ("travel rad", "{:.3f}"),
    ("travel deg", "{:.1f}"),
    ("time s", "{:.2f}"),
    ("collision", "{:.0%}"),
    ("invalid", "{:.0%}"),
    ("mean gap", "{}"),
    ("IQM gap", "{}"),
    ("ms/step", "{:.3f}"),
)


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2%}"


def table(results: dict[str, Any]) -> str:
    """The results as an aligned text table, one row per policy (files written before
    ``mean_gap`` and ``iqm_gap`` existed are read too: ``agents.evaluation.with_gaps``).
    A line under the table says how many tasks the IQM gap left out, if any."""
    results = with_gaps(results)
    rows = [[title for title, _ in COLUMNS]]
    skipped = 0
    for name, m in results["policies"].items():
        skipped = max(skipped, m.get("iqm_gap_skipped") or 0)
        values = (
            name, m["success_rate"], f"{m['mean_return']:.3f} ± {m['std_return']:.3f}",
            m["mean_travel"], m["mean_travel_deg"], m["mean_time"], m["collision_rate"],
            m["invalid_rate"], _percent(m["mean_gap"]), _percent(m["iqm_gap"]),
            m["decision_ms"],
        )
        rows.append([fmt.format(v) for (_, fmt), v in zip(COLUMNS, values, strict=True)])
    widths = [max(len(row[c]) for row in rows) for c in range(len(COLUMNS))]
    lines = ["  ".join(cell.rjust(w) if c else cell.ljust(w)
                       for c, (cell, w) in enumerate(zip(row, widths, strict=True)))
             for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    if skipped:
        lines.append(f"IQM gap: {skipped} of {results['episodes']} tasks left out (the "
                     "oracle's return is 0 there: no scale to measure a shortfall by)")
    return "\n".join(lines)


def plot(results: dict[str, Any], path: str | Path) -> None:
    """Bars of return, travel (degrees) and success per policy; whiskers one std."""
    import matplotlib

    matplotlib.use("Agg")  # files only: no display needed
    import matplotlib.pyplot as plt
    import numpy as np

    names = list(results["policies"])
    metrics = [results["policies"][n] for n in names]
    panels = (
        ("return", [m["mean_return"] for m in metrics], [m["std_return"] for m in metrics]),
        ("travel (deg)", [np.degrees(m["mean_travel"]) for m in metrics],
         [np.degrees(m["std_travel"]) for m in metrics]),
        ("success rate", [m["success_rate"] for m in metrics], None),
    )
    figure, axes = plt.subplots(1, 3, figsize=(4 + 1.2 * len(names), 4), layout="constrained")
    x = np.arange(len(names))
    for axis, (title, means, spread) in zip(axes, panels, strict=True):
        axis.bar(x, means, yerr=spread, capsize=4, color="tab:blue", alpha=0.8)
        axis.set_title(title)
        axis.set_xticks(x, names, rotation=30, ha="right")
        axis.grid(axis="y", alpha=0.3)
    axes[2].set_ylim(0, 1.05)
    figure.suptitle(
        f"{results['env']}: {results['episodes']} episodes from seed {results['seed']} "
        "(whiskers: ±1 std)"
    )
    figure.savefig(path, dpi=120)
    plt.close(figure)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="python -m train.evaluate", description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--env", required=True, help="env id, e.g. IKBranch/Anthropomorphic-v4")
    parser.add_argument("--env-kwargs", type=json.loads, default={},
                        help='JSON dict of env arguments, e.g. \'{"n_waypoints": 12}\'')
    parser.add_argument("--policy", action="append", required=True, dest="policies",
                        help="baseline name, SB3 model .zip or MODULE:ATTR (repeatable)")
    parser.add_argument("--wrapper", action="append", default=[], dest="wrappers",
                        metavar="MODULE:ATTR",
                        help="wrap every evaluated env: a Gymnasium wrapper class or a "
                             "callable env -> env (repeatable, applied in order)")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=TEST_SEED,
                        help=f"first task seed (default {TEST_SEED}: held out from training)")
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--plot", type=Path, help="draw the comparison here (.png)")
    args = parser.parse_args(argv)
    if not isinstance(args.env_kwargs, dict):
        parser.error("--env-kwargs must be a JSON object")
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    return args


def _wrapper(spec: str) -> Any:
    """The wrapper ``--wrapper MODULE:ATTR`` names; ``ValueError`` if it is none."""
    wrapper = resolve(spec)
    if not callable(wrapper):
        raise ValueError(f"--wrapper {spec}: {type(wrapper).__name__} is no wrapper (a "
                         "Gymnasium wrapper class or a callable env -> env)")
    return wrapper


def main(argv: list[str] | None = None) -> dict[str, Any]:
    args = parse_args(argv)
    try:
        wrappers = [_wrapper(spec) for spec in args.wrappers]
        results = evaluate(args.env, args.policies, args.episodes, args.seed,
                           held_out(args.env, args.env_kwargs), wrappers=wrappers)
    except ValueError as error:  # unknown policy, bad zip, mismatched env: a usage error
        raise SystemExit(f"error: {error}") from error
    results["wrappers"] = list(args.wrappers)  # as given: MODULE:ATTR
    print(table(results))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results, indent=2) + "\n")
    if args.plot:
        args.plot.parent.mkdir(parents=True, exist_ok=True)
        plot(results, args.plot)
    return results


if __name__ == "__main__":
    main()
