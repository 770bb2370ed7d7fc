"""Joint states over time: one ``sensor_msgs/JointState`` series, whoever recorded it.

A bag's ``/joint_states`` (perception: the robot's configuration beside each image, what the
synthetic recorder writes) and a controller's or the simulator's log (execution: what the
robot did, compared with a plan) are the same data, so they are one type: joint names,
times, positions and, when recorded, velocities. Readers and writers of the formats stay
with their packages (bags: :mod:`gaide_core.ros`; log CSV: ``execution.joint_log``).

Times are seconds relative to ``start_ns`` (absolute, e.g. ROS time, ns): a log read from a
CSV keeps its times exactly, and :attr:`JointStates.stamps_ns` gives the ROS stamps back
(exactly for a series shorter than 26 days).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gaide_core.errors import GaideError
from gaide_core.types import FloatArray, IntArray

__all__ = ["JointStates"]


@dataclass(frozen=True, kw_only=True)
class JointStates:
    """Joint states sorted by time (at least one sample of at least one joint).

    ``error`` is the exception the checks here raise: the stage that made the series
    (``BagError`` for a bag's, ``ExecutionError`` for a controller log).
    """

    names: tuple[str, ...]
    t: FloatArray  # (N,) s, strictly increasing, relative to ``start_ns``
    q: FloatArray  # (N, len(names)) rad
    qd: FloatArray | None = None  # (N, len(names)) rad/s
    start_ns: int = 0  # absolute time (ns) of t = 0
    error: type[GaideError] = field(default=GaideError, repr=False, compare=False)

    def __post_init__(self) -> None:
        n, dof = len(self.t), len(self.names)
        if n < 1 or dof < 1:
            raise self.error(
                f"joint states need at least one sample and one joint, got {n} x {dof}"
            )
        if len(set(self.names)) != dof:
            raise self.error(f"joint names repeat: {list(self.names)}")
        for what, arr in (("positions", self.q), ("velocities", self.qd)):
            if arr is not None and arr.shape != (n, dof):
                raise self.error(
                    f"joint {what} have shape {arr.shape}; expected ({n}, {dof}) for {n} "
                    f"samples of {dof} joints"
                )
        if np.any(np.diff(self.t) <= 0):
            raise self.error("joint state times must increase strictly (sorted, no repeats)")

    @classmethod
    def from_stamps(
        cls,
        names: tuple[str, ...],
        stamps_ns: IntArray,
        q: FloatArray,
        qd: FloatArray | None = None,
        error: type[GaideError] = GaideError,
    ) -> JointStates:
        """The series of samples stamped ``stamps_ns`` (absolute ns, increasing)."""
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        start = int(stamps[0]) if len(stamps) else 0
        t = (stamps - start).astype(np.float64) * 1e-9
        return cls(names=names, t=t, q=q, qd=qd, start_ns=start, error=error)

    @property
    def stamps_ns(self) -> IntArray:
        """Absolute stamps (ns) of the samples: ``start_ns + t``."""
        return self.start_ns + np.rint(self.t * 1e9).astype(np.int64)

    def at(self, stamp_ns: int) -> FloatArray:
        """Positions at the sample nearest in time to ``stamp_ns`` (absolute ns)."""
        i = int(np.argmin(np.abs(self.stamps_ns - stamp_ns)))
        return self.q[i].copy()

    def select(self, names: tuple[str, ...]) -> JointStates:
        """The series with its joints reordered as ``names`` (``error`` naming the joints
        it lacks and its other ones)."""
        missing = [n for n in names if n not in self.names]
        if missing:
            extra = [n for n in self.names if n not in names]
            raise self.error(
                f"the joint states lack joints {missing} (their joints not asked for: {extra})"
            )
        idx = [self.names.index(n) for n in names]
        return JointStates(
            names=names,
            t=self.t,
            q=self.q[:, idx],
            qd=None if self.qd is None else self.qd[:, idx],
            start_ns=self.start_ns,
            error=self.error,
        )
