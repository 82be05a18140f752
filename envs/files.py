"""Files that appear whole: written beside their target, then renamed into place.

    write_atomically(path, "text")                      # str (UTF-8, written as given)
    write_atomically(path, b"bytes")
    write_atomically(path, model.save)                  # a function writing a given path
    write_all_atomically({csv: text, gif: data})        # several files, all or none

Each file is first written in full to a temporary file in the target's directory (so the
rename stays within one file system), flushed to disk (``fsync``), given the permissions
an ordinary ``open(path, "w")`` would give it (a new file ``0o666`` less the umask, unless
``mode`` says otherwise; an existing file keeps its own), then renamed over the target
(``os.replace``, atomic on POSIX). A reader, or a process resuming after a crash, sees the
old file or the new one, never half of one. When anything fails before the renames (the
content cannot be written, a function raises, the disk is full) every temporary file is
removed and every target is untouched.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TypeVar

#: What a file receives: its text (UTF-8, newlines as given), its bytes, or a function that
#: writes the file at the path it is given, as a string (a library's ``save(path)``).
Content = str | bytes | Callable[[str], object]

#: A target path, as a string or a path object.
Target = TypeVar("Target", bound=str | os.PathLike[str])

_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)


def write_atomically(path: str | os.PathLike[str], content: Content, *,
                     mode: int = 0o666) -> Path:
    """Write ``content`` to ``path`` so that the file appears whole or not at all (module
    docstring); returns the path. ``mode`` as in ``os.open``: the umask still applies."""
    return write_all_atomically({path: content}, mode=mode)[0]


def write_all_atomically(outputs: Mapping[Target, Content], *,
                         mode: int = 0o666) -> list[Path]:
    """Write every file of ``outputs`` beside its target, then rename each into place: on
    any failure before the renames no target changes. Returns the paths, in order."""
    staged: list[tuple[Path, Path]] = []
    try:
        for target, content in outputs.items():
            path = Path(target)
            staged.append((_temporary(path, mode), path))
            _fill(staged[-1][0], content)
        for temporary, path in staged:
            os.replace(temporary, path)
        for directory in dict.fromkeys(path.parent for _, path in staged):
            _sync_directory(directory)
    finally:
        for temporary, _ in staged:
            temporary.unlink(missing_ok=True)
    return [path for _, path in staged]


def _temporary(path: Path, mode: int) -> Path:
    """A new empty file beside ``path``: with ``path``'s own permissions when it exists
    (as ``open(path, "w")`` keeps them), else created with ``mode`` less the umask (the
    kernel applies it, as to any new file)."""
    keep = None
    with contextlib.suppress(OSError):
        existing = path.stat()
        if stat.S_ISREG(existing.st_mode):
            keep = stat.S_IMODE(existing.st_mode)
    for _ in range(100):
        temporary = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
        try:
            handle = os.open(temporary, _FLAGS, mode if keep is None else 0o600)
        except FileExistsError:
            continue
        try:
            if keep is not None:
                os.fchmod(handle, keep)
        finally:
            os.close(handle)
        return temporary
    raise FileExistsError(f"no free temporary name beside {path}")


def _fill(temporary: Path, content: Content) -> None:
    """Write ``content`` to ``temporary`` and flush it to disk."""
    if callable(content):
        content(str(temporary))  # writes into the file it is given: it keeps its mode
    else:
        data = content.encode("utf-8") if isinstance(content, str) else bytes(content)
        with open(temporary, "wb") as stream:
            stream.write(data)
    with open(temporary, "rb+") as stream:
        os.fsync(stream.fileno())


def _sync_directory(directory: Path) -> None:
    """Flush the directory entry of a rename to disk (POSIX; a no-op where unsupported)."""
    try:
        handle = os.open(directory if str(directory) else ".", os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(handle)
    except OSError:
        pass
    finally:
        os.close(handle)
