"""``ikbranch``: one console command over the package's entry points.

    ikbranch plan      --arm NAME --waypoints FILE --out plan.csv …   (train.plan)
    ikbranch train     --algo … --env … --run-dir …                   (python -m train)
    ikbranch evaluate  --env … --policy … …                           (python -m train.evaluate)
    ikbranch demo      [--run-dir runs/demo] …                        (python -m train.demo)
    ikbranch sweep     --env … [--algo …] [--seeds 0-4] …             (python -m train.sweep)
    ikbranch aggregate [--root runs/sweep] [--out F]                  (python -m train.aggregate)
    ikbranch export    MODEL.zip --env ID [--out F.npz]              (python -m train.export)
    ikbranch warm-up   [--processes 2]                                (envs.precompile)

Every subcommand forwards its arguments unchanged to that module's ``main`` (so
``ikbranch train --help`` is ``python -m train --help``); the ``python -m`` forms keep
working. Each module is imported only when its subcommand runs (``ikbranch --help`` and
``ikbranch plan`` never import torch).
"""

from __future__ import annotations

import difflib
import importlib
import sys
from collections.abc import Sequence

#: subcommand -> (module whose ``main(argv)`` runs it, one-line description).
COMMANDS: dict[str, tuple[str, str]] = {
    "plan": ("ikbranch_gym.train.plan",
             "choose an IK branch per waypoint of a waypoint file (a plan CSV)"),
    "train": ("ikbranch_gym.train.__main__",
              "train PPO or MaskablePPO on an env id (python -m train)"),
    "evaluate": ("ikbranch_gym.train.evaluate",
                 "compare policies on the same tasks (python -m train.evaluate)"),
    "demo": ("ikbranch_gym.train.demo",
             "the worked example, training and comparison (python -m train.demo)"),
    "sweep": ("ikbranch_gym.train.sweep",
              "env x algorithm x seed trials on Ray Tune (python -m train.sweep)"),
    "aggregate": ("ikbranch_gym.train.aggregate",
                  "interval estimates over a sweep (python -m train.aggregate)"),
    "export": ("ikbranch_gym.train.export",
               "a trained model's actor as a numpy-only .npz (python -m train.export)"),
    "warm-up": ("ikbranch_gym.envs.precompile",
                "compile every kernel into numba's cache ahead of the first env"),
}


#: subcommand -> the optional dependencies (``pyproject.toml`` extra) it needs (warm-up
#: needs the environments' own only).
EXTRAS = {"plan": "plan", "train": "train", "evaluate": "train", "demo": "train",
          "sweep": "sweep", "aggregate": "sweep", "export": "train"}


def usage() -> str:
    width = max(map(len, COMMANDS))
    lines = ["usage: ikbranch COMMAND [ARGS ...]", "",
             "IK-branch selection for MuJoCo arms: plans, training, evaluation.", "",
             "commands:"]
    lines += [f"  {name:<{width}}  {text}" for name, (_, text) in COMMANDS.items()]
    lines += ["", "'ikbranch COMMAND --help' describes a command's arguments.",
              "options:", "  -h, --help  show this message and exit",
              "  --version   show the package version and exit"]
    return "\n".join(lines)


def _exit_status(result: object) -> int:
    """A forwarded ``main``'s result as an exit status: ints as they are; anything else
    (``None``, or train.evaluate's results dict) means it finished: 0."""
    return result if isinstance(result, int) else 0


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv:
        print(usage(), file=sys.stderr)
        return 2
    command, rest = argv[0], argv[1:]
    if command in ("-h", "--help", "help"):
        print(usage())
        return 0
    if command == "--version":
        from importlib import metadata

        try:
            print(f"ikbranch {metadata.version('ikbranch-gym')}")
        except metadata.PackageNotFoundError:
            print("ikbranch (ikbranch-gym not installed)")
        return 0
    if command not in COMMANDS:
        close = difflib.get_close_matches(command, COMMANDS, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        print(f"ikbranch: unknown command {command!r}{hint}; choose one of "
              f"{', '.join(COMMANDS)} ('ikbranch --help' lists them)", file=sys.stderr)
        return 2
    try:
        return _exit_status(importlib.import_module(COMMANDS[command][0]).main(rest))
    except ModuleNotFoundError as error:
        # An optional dependency the command needs (anything but this package itself).
        if (error.name is None or error.name.partition(".")[0] == "ikbranch_gym"
                or command not in EXTRAS):
            raise
        print(f"ikbranch {command} needs {error.name!r}, which is not installed: "
              f"pip install 'ikbranch-gym[{EXTRAS[command]}]'", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
