"""Atomic file writes: a reader sees the old file or the new one, never half of one."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from gaide_core.errors import GaideError


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
