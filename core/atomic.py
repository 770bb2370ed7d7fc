"""Atomic file writes: a reader sees the old file or the new one, never half of one."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from core.errors import GaideError


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
