"""Atomic file writes, the one way every package writes its outputs: a reader sees the old
file (or folder) or the new one, never half of one, and a failure (a full disk, a read-only
folder) leaves the old one and raises the caller's stage error (``error=``) naming the file.

- :func:`write_bytes_atomic`: bytes to a temporary sibling, then renamed over the file;
- :func:`write_file_atomic`: for libraries that only write to a path (OpenCV, matplotlib,
  Open3D, torch): they write a temporary sibling, checked whole, then renamed;
- :func:`staged_outputs` and :func:`write_files_atomic`: several files or folders (a ROS2 bag)
  all or none: each written to a temporary sibling, all renamed into place only when all
  were written;
- :func:`verify_file`: the check that a written file is whole (writers that hit a full disk
  do not always say so).

Shared because every stage writes files and none may import another's writer.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from gaide_core.errors import GaideError

__all__ = [
    "Content",
    "staged_outputs",
    "verify_file",
    "write_bytes_atomic",
    "write_file_atomic",
    "write_files_atomic",
]

#: What :func:`write_files_atomic` writes to a path: bytes, or a function writing the file
#: (or folder) at the path it is given.
Content = bytes | Callable[[Path], object]


def write_bytes_atomic(
    path: str | os.PathLike[str], data: bytes, error: type[GaideError] = GaideError
) -> Path:
    """Write ``data`` to a temporary file beside ``path``, then rename it over ``path``;
    an OS error becomes ``error`` (the caller's stage) naming the file."""
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as err:
        raise error(f"cannot write {target}: {err}") from err
    try:
        # mkstemp makes the file private (0600); give it the mode a plain open() would
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except OSError as err:
        Path(tmp).unlink(missing_ok=True)
        raise error(f"cannot write {target}: {err}") from err
    return target


def write_file_atomic(
    path: str | os.PathLike[str],
    write: Callable[[Path], object],
    error: type[GaideError] = GaideError,
) -> Path:
    """Let ``write`` write the file at a hidden temporary path beside ``path`` (libraries
    that only write to a path: OpenCV, matplotlib, Open3D), check it is whole
    (:func:`verify_file`), then rename it over ``path``. On any failure the temporary file
    goes and ``path`` stays as it was; an OS error becomes ``error`` naming the file."""
    target = Path(path)
    tmp = target.with_name(f".{target.stem}.{os.getpid()}.tmp{target.suffix}")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        write(tmp)
        verify_file(tmp, None, error, name=target.name)
        os.replace(tmp, target)
    except OSError as err:
        raise error(f"cannot write {target}: {err.strerror or err}") from err
    finally:
        tmp.unlink(missing_ok=True)
    return target


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"


def verify_file(
    path: Path, size: int | None, error: type[GaideError] = GaideError, *, name: str = ""
) -> None:
    """``error`` unless the file (or folder) at ``path`` is whole: ``size`` bytes when given,
    else not empty (a folder: not empty), and a PNG with its signature and end chunk.
    Writers that hit a full disk do not always say so. ``name`` names it in the message."""
    label = name or path.name
    try:
        if path.is_dir():
            if not any(path.iterdir()):
                raise error(f"{label}: the folder was left empty (is the disk full?)")
            return
        got = path.stat().st_size
        if (size is not None and got != size) or got == 0:
            wanted = "" if size is None else f" of {size:,}"
            raise error(f"{label}: {got:,} bytes written{wanted} (is the disk full?)")
        if path.suffix.lower() == ".png":
            with path.open("rb") as f:
                head = f.read(8)
                f.seek(max(got - 8, 0))
                tail = f.read(8)
            if head != _PNG_SIGNATURE or tail != _PNG_END:
                raise error(f"{label}: the PNG is incomplete (is the disk full?)")
    except FileNotFoundError as err:
        raise error(f"{label}: nothing was written") from err
    except OSError as err:
        raise error(f"{label} cannot be checked: {err.strerror or err}") from err


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
    targets: Sequence[str | os.PathLike[str]], error: type[GaideError] = GaideError
) -> Iterator[list[Path]]:
    """Yield one temporary path per target (a hidden sibling folder holding the target's
    name; not created).

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


def write_files_atomic(
    files: Sequence[tuple[str | os.PathLike[str], Content]], error: type[GaideError] = GaideError
) -> list[Path]:
    """Write ``files`` ((path, :data:`Content`) pairs) all or none (:func:`staged_outputs`),
    each checked whole (:func:`verify_file`: bytes, their size) before any is renamed into
    place; returns the paths. An OS error writing one becomes ``error`` naming the file."""
    targets = [Path(p) for p, _ in files]
    with staged_outputs(targets, error) as staged:
        for target, tmp, (_, content) in zip(targets, staged, files, strict=True):
            try:
                if isinstance(content, bytes):
                    tmp.write_bytes(content)
                else:
                    content(tmp)
            except OSError as err:
                raise error(f"cannot write {target}: {err.strerror or err}") from err
            verify_file(
                tmp, len(content) if isinstance(content, bytes) else None, error, name=target.name
            )
    return targets
