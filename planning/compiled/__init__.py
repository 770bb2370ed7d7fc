"""The compiled planning core: numba kernels for collision checking and planning.

Python objects never enter a kernel: :mod:`planning.compiled.tables` exports the robot,
sphere model and world once as flat arrays (:mod:`planning.compiled.layout`), and the
kernels (:mod:`~planning.compiled.geometry`, :mod:`~planning.compiled.validity`) take only
those. :class:`~planning.compiled.checker.CompiledChecker` is the Python face.
"""

__all__ = [
    "checker",
    "geometry",
    "layout",
    "rrtc_kernel",
    "shortcut_kernel",
    "tables",
    "validity",
    "warmup",
]
