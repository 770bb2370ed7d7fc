"""Staged outputs (:func:`~gaide_core.atomic.verify_file` re-exported for their writers): a reader sees the old file (or folder) or the new one, never half of one.

:func:`staged_outputs` hands out temporary sibling paths to write into and, only when every
one of them was written without an error, renames them all into place. A failure anywhere
removes every temporary path and leaves the targets as they were, so a command that writes
several files writes all of them or none.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path

from gaide_core.atomic import verify_file
from gaide_core.errors import ExecutionError, GaideError

__all__ = ["staged_outputs", "verify_file"]


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def _replace(staged: Path, target: Path) -> None:
    """Rename ``staged`` over ``target``; a folder target is swapped via a third name (a
    folder cannot be renamed over a non-empty one)."""
    if target.is_dir() and not target.is_symlink():
        old = target.with_name(f".{target.name}.old-{os.getpid()}")
        _remove(old)
        os.rename(target, old)
        try:
            os.rename(staged, target)
        except OSError:
            os.rename(old, target)
            raise
        _remove(old)
    else:
        os.replace(staged, target)


@contextlib.contextmanager
def staged_outputs(
    targets: Sequence[str | os.PathLike[str]], error: type[GaideError] = ExecutionError
) -> Iterator[list[Path]]:
    """Yield one temporary path per target (same folder, same name suffix; not created).

    Write each output to its temporary path (a file, or a folder for a ROS2 bag). On a clean
    exit every temporary path is renamed over its target (replacing an existing one); on an
    exception every temporary path is removed and the exception propagates. ``OSError``
    raised by the renames is translated into ``error`` naming the target.
    """
    paths = [Path(t) for t in targets]
    if len({p.resolve() for p in paths}) != len(paths):
        raise error(f"the same output is named twice: {[str(p) for p in paths]}")
    staging: list[Path] = []
    try:
        for target in paths:
            try:
                target.parent.mkdir(parents=True, exist_ok=True)
                folder = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
            except OSError as err:
                raise error(f"cannot write {target}: {err}") from err
            staging.append(folder)
        yield [folder / target.name for folder, target in zip(staging, paths, strict=True)]
        for folder, target in zip(staging, paths, strict=True):
            staged = folder / target.name
            if not staged.exists():
                raise error(f"{target}: nothing was written")
        for folder, target in zip(staging, paths, strict=True):
            try:
                _replace(folder / target.name, target)
            except OSError as err:
                raise error(f"cannot write {target}: {err}") from err
    finally:
        for folder in staging:
            shutil.rmtree(folder, ignore_errors=True)
