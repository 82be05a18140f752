"""``python -m train``: train PPO or MaskablePPO on a registered IKBranch env.

    python -m train --algo maskable_ppo --env IKBranch/ToolTransfer-v2 \\
        --timesteps 150000 --seed 0 --n-envs 2 --run-dir runs/tool_transfer

Hyper-parameters come from ``configs/hyperparams.yml`` (or ``--config``), keyed by env id;
``--timesteps``, ``--n-envs``, ``--env-kwargs`` and ``--hyperparams`` override them.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ikbranch_gym.train.hyperparams import ALGORITHMS
from ikbranch_gym.train.training import VEC_ENVS, RunConfig, train


def _json_object(text: str) -> dict:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON: {exc}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError("must be a JSON object")
    return value


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m train", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--algo", required=True, choices=sorted(ALGORITHMS))
    p.add_argument("--env", required=True, help="a registered id, e.g. IKBranch/ToolTransfer-v2")
    p.add_argument("--config", help="YAML file keyed by env id (default configs/hyperparams.yml)")
    p.add_argument("--env-kwargs", type=_json_object, default={}, help="JSON object")
    p.add_argument("--hyperparams", type=_json_object, default={},
                   help="JSON object of algorithm arguments overriding the config")
    p.add_argument("--timesteps", type=int)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--n-envs", type=int)
    p.add_argument("--run-dir", required=True, type=Path)
    p.add_argument("--resume", action="store_true", help="continue from checkpoints/latest.zip")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--verbose", type=int, default=0)
    p.add_argument("--torch-threads", type=int, default=1, help="learner threads (default 1)")
    p.add_argument("--vec-env", choices=VEC_ENVS, default="native",
                   help="how the n_envs run: the natively batched vector env in this process "
                        "(native, the default), single envs in worker processes (subproc) or "
                        "one after another (dummy); the learner sees the same data")
    p.add_argument("--env-threads", type=int, default=1,
                   help="threads of the native vector env: its n_envs in this many groups "
                        "stepped side by side (default 1; the same data whatever the number)")
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = parser().parse_args(argv)
    import ikbranch_gym.envs as envs

    if args.env not in envs.ENV_IDS:
        parser().error(f"unknown env id {args.env!r}; registered: {', '.join(envs.ENV_IDS)}")
    run = RunConfig(
        algo=args.algo, env_id=args.env, seed=args.seed, run_dir=args.run_dir,
        timesteps=args.timesteps, n_envs=args.n_envs, config=args.config,
        env_kwargs=args.env_kwargs, hyperparams=args.hyperparams, resume=args.resume,
        progress_bar=not args.no_progress, verbose=args.verbose,
        torch_threads=args.torch_threads, vec_env=args.vec_env, env_threads=args.env_threads,
    )
    try:
        train(run, argv)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"trained model: {args.run_dir / 'model.zip'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
