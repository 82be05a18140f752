"""Time from ``gym.make`` to the first step, numba's compile cache warm and cold.

    .venv/bin/python benchmarks/startup.py [--id IKBranch/Anthropomorphic-v1] [--runs 3]

Each run is a fresh Python process: ``import ikbranch_gym``, ``gym.make(id)``, ``reset(seed=0)``
and one masked step, timed from just before ``gym.make``. *Warm*: numba's on-disk cache
(``__pycache__`` beside the sources, filled by ``make``'s warm-up step) holds the compiled
kernels. *Cold*: ``NUMBA_CACHE_DIR`` points at an empty folder, so every kernel compiles
in that process. Printed: the best of ``--runs`` warm runs and the one cold run.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

CHILD = """
import time
import gymnasium as gym
import numpy as np
import ikbranch_gym.envs as envs
tick = time.perf_counter()
env = gym.make({env_id!r})
env.reset(seed=0)
env.step(int(np.flatnonzero(env.unwrapped.action_masks())[0]))
print(time.perf_counter() - tick)
"""


def _run(env_id: str, extra_env: dict[str, str]) -> float:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), **extra_env}
    out = subprocess.run([sys.executable, "-c", CHILD.format(env_id=env_id)], env=env,
                         check=True, capture_output=True, text=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--id", default="IKBranch/Anthropomorphic-v1")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    _run(args.id, {})  # fills the on-disk cache if it was empty
    warm = min(_run(args.id, {}) for _ in range(args.runs))
    with tempfile.TemporaryDirectory() as empty:
        cold = _run(args.id, {"NUMBA_CACHE_DIR": empty})
    print(f"{args.id}: gym.make to first step {warm:.2f} s with numba's cache warm, "
          f"{cold:.2f} s cold (every kernel compiled)")


if __name__ == "__main__":
    main()
