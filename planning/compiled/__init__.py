"""The compiled planning core: numba kernels for collision checking and planning.

Python objects never enter a kernel: :mod:`planning.compiled.tables` exports the robot,
sphere model and world once as flat arrays (:mod:`planning.compiled.layout`), and the
kernels (:mod:`~planning.compiled.geometry`, :mod:`~planning.compiled.validity`,
:mod:`~planning.compiled.lanes`) take only those.
:class:`~planning.compiled.checker.CompiledChecker` is the Python face. The planners' kernels
are :mod:`~planning.compiled.rrtc_kernel` and :mod:`~planning.compiled.shortcut_kernel`, and
:mod:`~planning.compiled.band_kernel` serves the oracle's elastic band.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

__all__ = [
    "band_kernel",
    "checker",
    "geometry",
    "lanes",
    "layout",
    "rrtc_kernel",
    "shortcut_kernel",
    "tables",
    "trig",
    "validity",
    "warmup",
]

_STAMP = "kernels.sha256"


def drop_stale_kernels(package: Path, constants: tuple[Path, ...] = ()) -> bool:
    """Delete numba's cached kernels in ``package/__pycache__`` unless they were compiled
    from the package's present sources and the modules in ``constants``; returns True when
    it deleted them.

    Numba keys a cached kernel by its own file's timestamp only. A kernel of validity.py
    that inlines a function of geometry.py would load its old machine code after an edit
    of geometry.py alone: stale answers, met while measuring a change here. Numba also
    freezes the value of a global it reads into the machine code, so the kernels that read
    planning.collision's constants (the clearance cap, the dense certificate's sizes) would
    keep the old values after an edit there. The stamp covers every source file of the
    package and the modules in ``constants``, so any edit recompiles every kernel."""
    digest = hashlib.sha256()
    for source in [*sorted(package.glob("*.py")), *constants]:
        digest.update(source.name.encode() + b"\0" + source.read_bytes())
    cache = package / "__pycache__"
    stamp = cache / _STAMP
    try:
        if stamp.read_text() == digest.hexdigest():
            return False
    except OSError:
        pass
    try:
        for kernel in [*cache.glob("*.nbi"), *cache.glob("*.nbc")]:
            kernel.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        stamp.write_text(digest.hexdigest())
    except OSError:  # a read-only install: numba then caches elsewhere, or not at all
        return False
    return True


# planning.collision: the constants the kernels share with the reference checker
drop_stale_kernels(Path(__file__).parent, (Path(__file__).parent.parent / "collision.py",))
