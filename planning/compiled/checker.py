"""The compiled collision checker: the numpy reference's interface, numba kernels inside.

:class:`CompiledChecker` builds the numpy reference's tables (spheres, pairs, displacement
bounds), exports them once with :mod:`planning.compiled.tables` and answers the hot queries
(configurations, edges, the first invalid edge of a path) in compiled code, with no Python
per configuration. Diagnosis, clearances and sphere centres for display stay in numpy.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.collision import Mask, SphereCollisionChecker
from planning.compiled import lanes, validity
from planning.compiled.tables import Tables, checker_tables


class CompiledChecker(SphereCollisionChecker):
    """Same constructor, same answers as :class:`SphereCollisionChecker` (the tests hold
    them to exact agreement), compiled."""

    backend = "compiled"

    def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.tables = checker_tables(self)
        # The kernels' leading arguments: ints, floats, the cloud's lattice.
        self._tables = self.tables.args()

    def kernel_tables(self) -> Tables:
        """The tables exported once, at construction (and again for a world raise)."""
        return self.tables

    def with_world_raise(self, raise_: Array) -> CompiledChecker:
        other = super().with_world_raise(raise_)
        assert isinstance(other, CompiledChecker)
        # The raised radii are tables of their own; the lattice is shared, not copied.
        other.tables = checker_tables(other)
        other._tables = other.tables.args()
        return other

    def config_valid(self, Q: Array) -> Mask:
        Q = self._batch(Q)
        if len(Q) == 1:  # the scalar check: a pass of lanes costs ~2 us more to set up
            return np.array([validity.config_valid(*self._tables, Q[0], self.margin)])
        out = np.empty(Q.shape[0], bool)
        lanes.configs_valid(*self._tables, Q, self.margin, out)
        return out

    def sphere_centers(self, Q: Array) -> Array:
        Q = self._batch(Q)
        out = np.empty((Q.shape[0], len(self.radii), 3))
        validity.sphere_centres(*self._tables, Q, out)
        return out

    def config_valid_one(self, q: Array) -> bool:
        """Validity of one configuration (dof,): the cheapest call, for per-state callbacks.
        The caller guarantees a finite, contiguous float64 (dof,) array."""
        return bool(validity.config_valid(*self._tables, q, self.margin))

    def edge_valid(self, q0: Array, q1: Array) -> bool:
        q0 = self.robot.as_configuration(q0)
        q1 = self.robot.as_configuration(q1)
        return self.edge_valid_one(q0, q1)

    def edge_valid_one(self, q0: Array, q1: Array) -> bool:
        """Certification of one edge between finite, contiguous float64 (dof,) arrays."""
        return bool(validity.edge_valid(*self._tables, q0, q1, self.margin, self.resolution))

    def edges_valid(self, Q0: Array, Q1: Array, *, coarse: bool = True) -> Mask:
        Q0, Q1 = self._batch(Q0), self._batch(Q1)
        if Q0.shape != Q1.shape:
            raise PlanningError(f"edge endpoints differ in shape: {Q0.shape} vs {Q1.shape}")
        out = np.empty(Q0.shape[0], bool)
        # The coarse pass never changes the answer: the kernel always runs it.
        validity.edges_valid(*self._tables, Q0, Q1, self.margin, self.resolution, out)
        return out

    def first_invalid_edge(self, path: Array) -> int | None:
        path = self._batch(path)
        if len(path) < 2:
            return None if bool(self.config_valid(path).all()) else 0
        bad = validity.first_invalid_edge(*self._tables, path, self.margin, self.resolution)
        return None if bad < 0 else int(bad)

    def edge_steps(self, Q0: Array, Q1: Array) -> npt.NDArray[np.int64]:
        Q0, Q1 = self._batch(Q0), self._batch(Q1)
        out = np.empty(Q0.shape[0], np.int64)
        I, F, _ = self._tables
        validity.edge_step_counts(I, F, Q0, Q1, self.resolution, out)
        return out

    def _batch(self, Q: Array) -> Array:
        # Contiguous float64: the kernels are compiled for that layout only.
        return np.ascontiguousarray(super()._batch(Q))
