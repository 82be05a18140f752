"""``python -m train.sweep``: env × algorithm × seed training trials on Ray Tune.

    python -m train.sweep --env IKBranch/Anthropomorphic-v4 --algo ppo --algo maskable_ppo \\
        --seeds 0-4 [--root runs/sweep] [--address auto] [--timesteps N] [--episodes 200]

Every trial runs the training code of ``python -m train`` into the same run directory
layout, ``<root>/runs/<EnvName>/<algo>/seed<k>`` (config, command, versions, checkpoints,
learning curve, ``model.zip``), then plays the final model on ``--episodes`` held-out
tasks (task seeds ``envs.seeds.TEST_SEED`` …; for ids that draw a clutter per episode,
scenes from the held-out range) beside the DP oracle, and writes ``evaluation.json``
there. Per env id one more trial evaluates every analytic baseline on the same tasks into
``<root>/baselines/<EnvName>.json``. ``python -m train.aggregate --root …`` turns all of it
into interval estimates.

Ray starts embedded on this machine's cores unless ``--address`` names an existing
cluster (``auto``, ``ray://host:10001``; the root must then be storage every node sees).
A failed trial is retried (``--max-failures``) and continues from its last checkpoint; a
trial whose ``evaluation.json`` exists at the trial's budget is skipped, so running the
same command again resumes a sweep (a record of another budget is no result of the trial:
it is trained again, into a root of its own). Across machines and runs:
``python -m train.aggregate --publish`` archives every finished trial's records (not its
checkpoints) in the repository, ``docs/results/sweep/trials`` (``ARCHIVE``, laid out as a
root), and a trial archived there is skipped too. A trial of a larger budget than its
row's (the budget was raised) waits in ``<archive>/staged/<steps>`` (``STAGED``, laid out
as a root, its model kept) until trials of its budget cover every seed of the row, which
they then replace; a sweep skips a staged trial as well, so a long sweep can be spread
over runs, a few seeds at a time, publishing after each.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import yaml

from ikbranch_gym.envs.files import write_atomically
from ikbranch_gym.train.hyperparams import ALGORITHMS

ROOT = Path(__file__).resolve().parent.parent
#: Finished trials' records, committed (``train.publish.archive``): a root without models.
ARCHIVE = ROOT / "docs" / "results" / "sweep" / "trials"
#: Held-out tasks per evaluation (at least 200 per row).
EPISODES = 200
BASELINES_TRIAL = "baselines"
#: A run directory's trained model (``python -m train`` writes it last).
MODEL = "model.zip"
#: The archive's root of trials waiting for the rest of their budget's seeds
#: (``train.publish.archive``).
STAGED = "staged"


def env_name(env_id: str) -> str:
    return env_id.split("/")[-1]


def run_dir(root: Path, env_id: str, algo: str, seed: int) -> Path:
    return Path(root) / "runs" / env_name(env_id) / algo / f"seed{seed}"


def baselines_path(root: Path, env_id: str) -> Path:
    return Path(root) / "baselines" / f"{env_name(env_id)}.json"


def staged_root(store: Path, steps: int | None = None) -> Path:
    """Where an archive keeps the trials of budgets larger than their rows' (``steps``:
    of that budget, a root of its own)."""
    return Path(store) / STAGED if steps is None else Path(store) / STAGED / str(int(steps))


def done_path(spec: dict[str, Any], root: Path | None = None) -> Path:
    """The file whose existence marks ``spec``'s trial finished (written last, atomically),
    under the spec's root (or ``root``)."""
    root, env_id = Path(spec["root"] if root is None else root), spec["env_id"]
    if spec["algo"] == BASELINES_TRIAL:
        return baselines_path(root, env_id)
    return run_dir(root, env_id, spec["algo"], int(spec["seed"])) / "evaluation.json"


def _run(spec: dict[str, Any], **options: Any) -> Any:
    """The ``train.training.RunConfig`` of a training trial (``options``: its other fields)."""
    from ikbranch_gym.train.training import RunConfig

    seed = int(spec["seed"])
    return RunConfig(algo=spec["algo"], env_id=spec["env_id"], seed=seed,
                     run_dir=run_dir(Path(spec["root"]), spec["env_id"], spec["algo"], seed),
                     timesteps=spec.get("timesteps"),
                     hyperparams=dict(spec.get("hyperparams") or {}), **options)


def budget(spec: dict[str, Any]) -> int:
    """A training trial's steps, as its training resolves them (``--timesteps``, else its
    hyperparameter overrides, else its config entry)."""
    from ikbranch_gym.train.training import resolve

    return int(resolve(_run(spec))["n_timesteps"])


def finished(spec: dict[str, Any]) -> Path | None:
    """The record of ``spec``'s trial if it is done: in its root, or archived (or staged
    there). A training trial's record counts only at the trial's budget: a record of
    another number of steps (the budget changed since) is no result of this trial."""
    steps = None if spec["algo"] == BASELINES_TRIAL else budget(spec)
    store = Path(spec.get("archive", ARCHIVE))
    roots = [spec["root"], store] + ([] if steps is None else [staged_root(store, steps)])
    for root in roots:
        path = done_path(spec, root)
        if path.exists() and (steps is None
                              or json.loads(path.read_text())["timesteps"] == steps):
            return path
    return None


def _write_json(path: Path, record: dict) -> None:
    """Atomically: a reader (or a resumed sweep) never sees half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(path, json.dumps(record, indent=1) + "\n")


def run_trial(spec: dict[str, Any]) -> dict[str, Any]:
    """One trial, without Ray: train (or resume, or skip) and evaluate; returns the record."""
    from ikbranch_gym.agents import BASELINES
    from ikbranch_gym.agents.evaluation import evaluate
    from ikbranch_gym.envs.seeds import TEST_SEED, held_out
    from ikbranch_gym.train.callbacks import LATEST
    from ikbranch_gym.train.imitation import RECORD as IMITATION_RECORD
    from ikbranch_gym.train.training import train

    root, env_id, algo = Path(spec["root"]), spec["env_id"], spec["algo"]
    episodes, env_kwargs = spec["episodes"], held_out(env_id, spec.get("env_kwargs"))
    done = finished(spec)
    if done is not None:
        return json.loads(done.read_text())
    if algo == BASELINES_TRIAL:
        target = done_path(spec)
        start = time.perf_counter()
        result = evaluate(env_id, list(BASELINES), episodes, TEST_SEED, env_kwargs=env_kwargs)
        record = {"env": env_id, "kind": BASELINES_TRIAL, "episodes": episodes,
                  "task_seed": TEST_SEED, "env_kwargs": env_kwargs,
                  "wall_minutes": (time.perf_counter() - start) / 60,
                  "policies": result["policies"]}
        _write_json(target, record)
        return record
    seed = int(spec["seed"])
    directory = run_dir(root, env_id, algo, seed)
    steps = budget(spec)
    trained_for = trained_model_steps(directory)
    if trained_for is not None and trained_for != steps:
        raise ValueError(f"{directory} holds a model trained for {trained_for} steps, where "
                         f"this trial's budget is {steps}: give the sweep another --root")
    start = time.perf_counter()
    if not (directory / MODEL).exists():
        resume = (directory / "checkpoints" / LATEST).exists()
        train(_run(spec, resume=resume, progress_bar=False),
              argv=["--algo", algo, "--env", env_id, "--seed", str(seed), "--run-dir",
                    str(directory)])
    trained = time.perf_counter()
    model = str(directory / MODEL)
    cloned = directory / IMITATION_RECORD
    result = evaluate(env_id, [model], episodes, TEST_SEED, env_kwargs=env_kwargs)
    record = {
        "env": env_id, "kind": "trial", "algo": algo, "seed": seed, "timesteps": steps,
        "train_minutes": (trained - start) / 60,
        "eval_minutes": (time.perf_counter() - trained) / 60,
        "episodes": episodes, "task_seed": TEST_SEED, "env_kwargs": env_kwargs,
        "policy": result["policies"][model.removesuffix(".zip")],
        "oracle": result["policies"]["dp_oracle"],
    }
    if cloned.exists():  # the oracle's episodes it started from (train.imitation)
        record["imitation_episodes"] = json.loads(cloned.read_text())["episodes"]
    _write_json(done_path(spec), record)
    return record


def trained_model_steps(directory: Path) -> int | None:
    """The steps the model in a run directory was trained for (its ``config.yml``), or
    None where it holds no model."""
    if not (directory / MODEL).exists():
        return None
    config = yaml.safe_load((directory / "config.yml").read_text())
    return int(config["hyperparams"]["n_timesteps"])


def _trainable(config: dict[str, Any]) -> None:
    from ray import tune

    record = run_trial(config["trial"])
    metrics = record.get("policy") or record["policies"]["dp_oracle"]
    tune.report({"success_rate": metrics["success_rate"],
                 "mean_return": metrics["mean_return"]})


def trials(env_ids: list[str], algos: list[str], seeds: list[int], root: Path,
           episodes: int, timesteps: int | None = None,
           hyperparams: dict | None = None, archive: Path = ARCHIVE) -> list[dict[str, Any]]:
    """The sweep's trials: every env × algorithm × seed, and one baselines trial per env.
    ``timesteps`` and ``hyperparams`` override the config for every trial."""
    specs = []
    for env_id in env_ids:
        common = {"root": str(root), "archive": str(archive), "env_id": env_id,
                  "episodes": episodes}
        specs.append({**common, "algo": BASELINES_TRIAL})
        specs += [{**common, "algo": algo, "seed": seed, "timesteps": timesteps,
                   "hyperparams": hyperparams or {}}
                  for algo in algos for seed in seeds]
    return specs


def _trial_name(trial: Any) -> str:
    spec = trial.config["trial"]
    seed = f"-seed{spec['seed']}" if "seed" in spec else ""
    return f"{env_name(spec['env_id'])}-{spec['algo']}{seed}-{trial.trial_id}"


def sweep(specs: list[dict[str, Any]], *, address: str | None = None,
          cpus_per_trial: float = 1.0, max_failures: int = 2, verbose: int = 1) -> Any:
    """Run ``specs`` as Ray Tune trials; returns Tune's ``ResultGrid``."""
    os.environ.setdefault("RAY_CHDIR_TO_TRIAL_DIR", "0")  # run directories are absolute
    import ray
    from ray import tune

    if not ray.is_initialized():
        if address:
            ray.init(address=address)
        else:
            ray.init(include_dashboard=False, configure_logging=False)
    storage = Path(specs[0]["root"]).resolve() / "tune"
    tuner = tune.Tuner(
        tune.with_resources(_trainable, {"cpu": cpus_per_trial}),
        param_space={"trial": tune.grid_search(specs)},
        tune_config=tune.TuneConfig(trial_dirname_creator=_trial_name),
        run_config=tune.RunConfig(
            name=time.strftime("sweep-%Y%m%d-%H%M%S"), storage_path=str(storage),
            failure_config=tune.FailureConfig(max_failures=max_failures), verbose=verbose,
        ),
    )
    return tuner.fit()


def _seeds(text: str) -> list[int]:
    seeds: list[int] = []
    for part in text.split(","):
        low, _, high = part.partition("-")
        seeds += list(range(int(low), int(high or low) + 1))
    return seeds


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m train.sweep", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", action="append", required=True, dest="envs",
                   help="a registered id (repeat for several)")
    p.add_argument("--algo", action="append", choices=tuple(ALGORITHMS), dest="algos",
                   help="default: every algorithm")
    p.add_argument("--seeds", default="0-4", type=_seeds, help="e.g. 0-4 or 0,2,5 (0-4)")
    # Relative to the working directory: a checkout's runs/, or an installed package user's.
    p.add_argument("--root", type=Path, default=Path("runs") / "sweep")
    p.add_argument("--archive", type=Path, default=ARCHIVE,
                   help="finished trials recorded here are skipped (default: the repository's)")
    p.add_argument("--address", help="an existing Ray cluster (default: embedded Ray)")
    p.add_argument("--timesteps", type=int, help="override every trial's budget")
    p.add_argument("--hyperparams", type=json.loads, default={},
                   help="JSON object overriding every trial's algorithm arguments")
    p.add_argument("--episodes", type=int, default=EPISODES, help=f"held-out tasks ({EPISODES})")
    p.add_argument("--cpus-per-trial", type=float, default=1.0)
    p.add_argument("--max-failures", type=int, default=2, help="retries of a failed trial")
    return p


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(sys.argv[1:] if argv is None else argv)
    import ikbranch_gym.envs as envs

    unknown = [env_id for env_id in args.envs if env_id not in envs.ENV_IDS]
    if unknown:
        parser().error(f"unknown env ids: {', '.join(unknown)}")
    specs = trials(args.envs, args.algos or list(ALGORITHMS), args.seeds, args.root.resolve(),
                   args.episodes, args.timesteps, args.hyperparams, args.archive.resolve())
    pending = [spec for spec in specs if finished(spec) is None]
    errors = 0
    if pending:
        results = sweep(pending, address=args.address, cpus_per_trial=args.cpus_per_trial,
                        max_failures=args.max_failures)
        errors = sum(1 for r in results if r.error)
    # Counted on disk: an interrupted sweep's unfinished trials need not report an error.
    done = sum(finished(spec) is not None for spec in specs)
    print(f"{done} of {len(specs)} trials finished ({errors} ended in an error); run "
          f"directories under {args.root / 'runs'}; rerun the same command to resume")
    return 0 if done == len(specs) else 1


if __name__ == "__main__":
    sys.exit(main())
