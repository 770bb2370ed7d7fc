"""A controller's joint-state log: what the robot (or the simulator) actually did, as a
:class:`~gaide_core.joints.JointStates` series (``error=ExecutionError``).

CSV layout (the simulator writes it; :func:`read_log_csv` reads it)::

    t,<joint>_pos,...,<joint>_vel,...

``t`` in s (from the log's start, or absolute: only differences matter to the comparison),
positions in rad, velocities in rad/s (optional when reading). :func:`read_log_csv` also
reads the CSV that ``rostopic echo -p /joint_states > log.csv`` writes (``%time`` in ns,
``field.header.stamp``, ``field.name0..``, ``field.position0..``, ``field.velocity0..``).

A log to compare with a plan needs at least two samples (:func:`check_log`); the readers
check that.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from execution.trajectory_io import read_csv_table
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates
from gaide_core.types import Array

MIN_SAMPLES = 2  # a log spans time: a comparison needs at least two samples


def check_log(log: JointStates, what: str = "the joint log") -> JointStates:
    """``log`` when it has at least :data:`MIN_SAMPLES` samples; ExecutionError naming
    ``what`` (the file) else."""
    n = len(log.t)
    if n < MIN_SAMPLES:
        raise ExecutionError(
            f"{what}: a joint log needs >= {MIN_SAMPLES} samples to compare, got {n}"
        )
    return log


def log_csv(log: JointStates) -> str:
    """The CSV text of ``log`` (see the module doc)."""
    header = ["t", *(f"{n}_pos" for n in log.names)]
    blocks = [log.t[:, None], log.q]
    if log.qd is not None:
        header += [f"{n}_vel" for n in log.names]
        blocks.append(log.qd)
    out = io.StringIO()
    out.write(",".join(header) + "\n")
    np.savetxt(out, np.hstack(blocks), delimiter=",", fmt="%.17g")
    return out.getvalue()


def read_log_csv(path: str | Path) -> JointStates:
    """A joint log from this module's CSV or from ``rostopic echo -p`` output."""
    source = Path(path)
    if not source.is_file():
        raise ExecutionError(f"log file {source} does not exist")
    first = source.open().readline()
    if first.startswith("%time"):
        return _read_rostopic_csv(source)
    header, data = read_csv_table(source)
    if not header or header[0] != "t":
        raise ExecutionError(
            f"{source}: the first column must be 't' (s), or the file must come from "
            "`rostopic echo -p` (first column '%time')"
        )
    names = tuple(h[: -len("_pos")] for h in header if h.endswith("_pos"))
    if not names:
        raise ExecutionError(f"{source}: no '<joint>_pos' columns")
    q = data[:, [header.index(f"{n}_pos") for n in names]]
    vel = [f"{n}_vel" for n in names]
    qd = data[:, [header.index(c) for c in vel]] if all(c in header for c in vel) else None
    return _sorted(source, names, data[:, 0], q, qd, 0)


def _read_rostopic_csv(source: Path) -> JointStates:
    import csv

    with source.open(newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    name_cols = sorted(
        (int(h[len("field.name") :]), i)
        for i, h in enumerate(header)
        if h.startswith("field.name") and h[len("field.name") :].isdigit()
    )
    pos_cols = {
        int(h[len("field.position") :]): i
        for i, h in enumerate(header)
        if h.startswith("field.position") and h[len("field.position") :].isdigit()
    }
    vel_cols = {
        int(h[len("field.velocity") :]): i
        for i, h in enumerate(header)
        if h.startswith("field.velocity") and h[len("field.velocity") :].isdigit()
    }
    if not name_cols or len(rows) < 3:
        raise ExecutionError(f"{source}: no joint names (field.nameN) or too few rows")
    names = tuple(rows[1][i] for _, i in name_cols)
    stamp_col = header.index("field.header.stamp") if "field.header.stamp" in header else 0
    try:
        stamps = np.array([int(r[stamp_col]) for r in rows[1:] if r], dtype=np.int64)
        q = np.array([[float(r[pos_cols[k]]) for k, _ in name_cols] for r in rows[1:] if r])
        qd = (
            np.array([[float(r[vel_cols[k]]) for k, _ in name_cols] for r in rows[1:] if r])
            if len(vel_cols) >= len(name_cols)
            else None
        )
    except (KeyError, ValueError, IndexError) as err:
        raise ExecutionError(f"{source}: malformed rostopic CSV ({err!r})") from err
    for r in rows[1:]:
        if r and tuple(r[i] for _, i in name_cols) != names:
            raise ExecutionError(f"{source}: the joint names change between rows")
    t = (stamps - stamps.min()).astype(float) * 1e-9
    return _sorted(source, names, t, q, qd, int(stamps.min()))


def _sorted(
    source: Path, names: tuple[str, ...], t: Array, q: Array, qd: Array | None, start_ns: int
) -> JointStates:
    order = np.argsort(t, kind="stable")
    t, q = t[order], q[order]
    qd = None if qd is None else qd[order]
    keep = np.r_[True, np.diff(t) > 0]  # drop repeated stamps
    try:
        log = JointStates(
            names=names,
            t=t[keep],
            q=q[keep],
            qd=None if qd is None else qd[keep],
            start_ns=start_ns,
            error=ExecutionError,
        )
    except ExecutionError as err:
        raise ExecutionError(f"{source}: {err}") from err
    return check_log(log, str(source))
