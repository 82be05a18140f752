"""``ikbranch warm-up``: every kernel compiled into numba's on-disk cache ahead of time.

A fresh install compiles the env's kernels when an env first resets and steps: about
three minutes of one core, inside the first ``gym.make`` … ``step``. This does it once,
in two processes (``envs.warm_up(processes=2)``), with the DP oracle's kernel: when
building a container image, or into a ``NUMBA_CACHE_DIR`` that Ray workers, test workers
and other virtual environments of the same version then load from (the caches are keyed by
the sources' text, not their path: ``envs.kinematics.compiled``).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="ikbranch warm-up",
        description="Compile every kernel of the envs and the DP oracle into numba's "
                    "on-disk cache (or load them from it).")
    parser.add_argument("--processes", type=int, choices=(1, 2), default=2,
                        help="compile in one process, or in two side by side (default)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    import ikbranch_gym.envs as envs
    from ikbranch_gym.agents import dp
    from ikbranch_gym.envs import jit
    from ikbranch_gym.envs.kinematics import compiled

    envs.warm_up(processes=args.processes)
    dp.warm_up()
    print(f"kernels ready in {time.perf_counter() - start:.1f} s, cached in "
          f"{jit.cache_directory()}, {compiled.cache_directory()} and "
          f"{dp.cache_directory()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
