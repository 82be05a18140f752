"""Publish results: ``python -m train.results [--env ID …] [--algo …] [--render-only]``.

For each env id and algorithm: train with the budget of ``configs/hyperparams.yml`` (seed 0,
run directory ``runs/results/<EnvName>/<algo>``), copy the final model to
``models/<EnvName>/<algo>.zip``, evaluate it beside every baseline on the held-out seeds
below, and store the numbers in ``docs/results/<EnvName>.json``; then render
``docs/results.md`` from all stored JSON files (``train.publish.write_results``, which renders
the multi-seed sweep's part too). ``tests/train/test_results.py`` re-evaluates the committed
models and checks they reproduce the published numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from ikbranch_gym.agents import BASELINES
from ikbranch_gym.agents.evaluation import ORACLE, evaluate
from ikbranch_gym.envs.seeds import TEST_SEED
from ikbranch_gym.train.hyperparams import ALGORITHMS
from ikbranch_gym.train.publish import RESULTS, write_results
from ikbranch_gym.train.training import RunConfig, train

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "models"
#: Every baseline beside the trained models; ``evaluate`` runs the oracle first anyway.
COMPARED_BASELINES = tuple(name for name in BASELINES if name != ORACLE)
#: Published evaluations play the tasks of seeds TEST_SEED, TEST_SEED + 1, … (envs.seeds:
#: no training run draws them).
EVAL_EPISODES = 50


def env_name(env_id: str) -> str:
    return env_id.split("/")[-1]


def model_path(env_id: str, algo: str) -> Path:
    return MODELS / env_name(env_id) / f"{algo}.zip"


def produce(env_id: str, algos: tuple[str, ...], seed: int = 0) -> dict[str, Any]:
    """Train (where no committed model exists) and evaluate; returns the stored record."""
    from ikbranch_gym.train.hyperparams import hyperparams_for

    record: dict[str, Any] = {"env": env_id, "eval_seed": TEST_SEED, "episodes": EVAL_EPISODES,
                              "training": {}}
    stored = RESULTS / f"{env_name(env_id)}.json"
    # Re-evaluating a committed model keeps the training time measured when it was trained.
    trained = json.loads(stored.read_text())["training"] if stored.exists() else {}
    for algo in algos:
        target = model_path(env_id, algo)
        run_dir = ROOT / "runs" / "results" / env_name(env_id) / algo
        if not target.exists():
            start = time.perf_counter()
            train(RunConfig(algo=algo, env_id=env_id, seed=seed, run_dir=run_dir,
                            progress_bar=False))
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(run_dir / "model.zip", target)
            minutes = (time.perf_counter() - start) / 60
        else:
            minutes = trained.get(algo, {}).get("wall_minutes")
        params = hyperparams_for(env_id, algo)
        record["training"][algo] = {
            "timesteps": params["n_timesteps"], "n_envs": params["n_envs"], "seed": seed,
            "wall_minutes": minutes,
            "command": f"python -m train --algo {algo} --env {env_id} --seed {seed} "
                       f"--run-dir {run_dir.relative_to(ROOT)}",
        }
    policies = [str(model_path(env_id, algo).relative_to(ROOT)) for algo in algos]
    here = Path.cwd()
    try:
        os.chdir(ROOT)  # model names in the record are repository paths
        results = evaluate(env_id, [*policies, *COMPARED_BASELINES], EVAL_EPISODES, TEST_SEED)
    finally:
        os.chdir(here)
    record["policies"] = results["policies"]
    record["evaluate_command"] = (
        f"python -m train.evaluate --env {env_id} "
        + " ".join(f"--policy {p}" for p in [*policies, *COMPARED_BASELINES])
        + f" --episodes {EVAL_EPISODES} --seed {TEST_SEED}"
    )
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{env_name(env_id)}.json").write_text(json.dumps(record, indent=2) + "\n")
    return record


def main(argv: list[str] | None = None) -> int:
    import ikbranch_gym.envs as envs

    parser = argparse.ArgumentParser(prog="python -m train.results", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", action="append", choices=envs.ENV_IDS, dest="env_ids")
    parser.add_argument("--algo", action="append", choices=tuple(ALGORITHMS), dest="algos")
    parser.add_argument("--render-only", action="store_true")
    args = parser.parse_args(argv)
    if not args.render_only:
        from ikbranch_gym.train.evaluate import plot

        # By default the ids already published here (the sweep publishes the newer ones).
        published = [json.loads(p.read_text())["env"] for p in sorted(RESULTS.glob("*.json"))]
        for env_id in args.env_ids or published:
            record = produce(env_id, tuple(args.algos or ALGORITHMS))
            plot({"env": env_id, "episodes": EVAL_EPISODES, "seed": TEST_SEED,
                  "policies": record["policies"]}, RESULTS / f"{env_name(env_id)}.png")
            print(f"{env_id}: done", flush=True)
    write_results()
    return 0


if __name__ == "__main__":
    sys.exit(main())
