"""Silencing what C++ libraries print straight to the process's stdout and stderr.

Open3D (Filament starting, RPly failing on a full disk: one line per vertex) writes to file
descriptors 1 and 2 around Python's streams, which would break the CLI's one-line errors.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator


@contextlib.contextmanager
def quiet_native_output() -> Iterator[None]:
    """Inside, file descriptors 1 and 2 go to /dev/null; Python's own output is flushed
    before and goes on after."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, devnull):
            os.close(fd)
