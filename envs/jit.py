"""numba's ``njit`` for the env's kernels, cached on disk under a hash of their sources.

numba stamps a cached function with its own file only: a kernel that calls a helper from
another module keeps running the old helper after the helper's file changed. The kernels
of the collision filter, move pricing, observation assembly and the batched episodes call
across modules, so they are cached in one directory named by a hash of every module in
``KERNEL_SOURCES``: any edit to one of them compiles all of them afresh (``make`` does it
once, ``ikbranch warm-up``), and no stale code can be loaded. A test checks that every module
of ``envs`` that compiles kernels is listed (``envs/kinematics`` has its own driver and
cache, ``envs.kinematics.compiled``). Where the sources lie does not matter
(``envs.kinematics.compiled.cached_njit``): installs of one version that share a
``NUMBA_CACHE_DIR`` compile the kernels once.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ikbranch_gym.envs.kinematics.compiled import cached_njit, writable_cache

_ROOT = Path(__file__).resolve().parent

#: The files and folders (relative to ``envs/``) whose kernels call each other, and this
#: one: the options the kernels are compiled with (numba's cache does not key on them).
KERNEL_SOURCES = ("models/filter", "models/native.py", "models/scenes.py", "moves.py",
                  "observations.py", "process.py", "stepping.py", "random_chain.py", "jit.py")


def _sources() -> list[Path]:
    files: list[Path] = []
    for name in KERNEL_SOURCES:
        path = _ROOT / name
        files += sorted(path.glob("*.py")) if path.is_dir() else [path]
    return files


@functools.cache
def cache_directory() -> str | None:
    """The cache directory of this version of the kernels: ``numba-<hash>``
    (``envs.kinematics.compiled.writable_cache``: under ``NUMBA_CACHE_DIR`` if set, else
    ``envs/__pycache__``, else the user's cache directory); None if none is writable
    (kernels are then compiled in every process)."""
    digest = hashlib.sha256()
    for source in _sources():
        digest.update(str(source.relative_to(_ROOT)).encode())
        digest.update(source.read_bytes())
    directory = writable_cache(f"numba-{digest.hexdigest()[:16]}", _ROOT / "__pycache__")
    return None if directory is None else str(directory)


def njit(function: Callable | None = None, **options: Any) -> Any:
    """``numba.njit(nogil=True, **options)``, cached in :func:`cache_directory`
    (``cached_njit``); usable bare (``@njit``) or with options (``@njit(inline="always")``).

    Without Python's lock: a vector env's groups of sub-envs step in threads of their own
    (``envs.vector_env``), one group's kernels running while another's Python does."""
    if function is None:
        return functools.partial(njit, **options)
    options.setdefault("nogil", True)
    directory = cache_directory()
    return cached_njit(function, None if directory is None else Path(directory), _ROOT,
                       **options)
