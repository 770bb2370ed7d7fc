"""Timed trajectories as CSV and JSON files, written and read back.

CSV: one header row, then one row per sample (comma-separated, '.' decimal point)::

    t,<joint>_pos,...,<joint>_vel,...,<joint>_acc,...,<joint>_jerk,...

with ``t`` in s from the trajectory's start (uniform at the controller rate), positions in
rad, velocities in rad/s, accelerations in rad/s^2, jerks in rad/s^3, joints in the URDF's
order and with its names. The ``_jerk`` columns are optional when reading.

JSON: an object with ``format: "gaide-trajectory"``, ``version: 1``, ``joint_names``,
``rate_hz``, ``mode``, ``status``, ``duration_s``, ``t`` (N,), ``q``, ``qd``, ``qdd``,
``jerk`` (N rows of dof values), and what the timing knew: ``path`` (the waypoints timed),
``limits``, ``segments``, ``figures``, ``notes``.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from execution.limits import JointLimits
from execution.timing_cfg import TimingMode
from execution.trajectory import SegmentInfo, TimedTrajectory, TimingStatus
from gaide_core.errors import ExecutionError, TimingError
from gaide_core.text_io import load_json
from gaide_core.types import Array

FORMAT = "gaide-trajectory"
COLUMNS = (("q", "pos"), ("qd", "vel"), ("qdd", "acc"), ("jerk", "jerk"))


def trajectory_csv(traj: TimedTrajectory) -> str:
    """The CSV text of ``traj`` (see the module doc)."""
    header = ["t"]
    blocks = [traj.t[:, None]]
    for attr, suffix in COLUMNS:
        arr = getattr(traj, attr)
        if arr is None:
            continue
        header += [f"{name}_{suffix}" for name in traj.joint_names]
        blocks.append(arr)
    out = io.StringIO()
    out.write(",".join(header) + "\n")
    np.savetxt(out, np.hstack(blocks), delimiter=",", fmt="%.17g")
    return out.getvalue()


def trajectory_json(traj: TimedTrajectory) -> str:
    """The JSON text of ``traj`` (see the module doc)."""
    payload: dict[str, Any] = {
        "format": FORMAT,
        "version": 1,
        "joint_names": list(traj.joint_names),
        "rate_hz": traj.rate_hz,
        "mode": None if traj.mode is None else traj.mode.value,
        "status": traj.status.value,
        "duration_s": traj.duration,
        "path": None if traj.path is None else traj.path.tolist(),
        "limits": None if traj.limits is None else traj.limits.as_dict(),
        "segments": [s.as_dict() for s in traj.segments],
        "figures": {k: _finite(v) for k, v in traj.figures.items()},
        "notes": list(traj.notes),
        "t": traj.t.tolist(),
        "q": traj.q.tolist(),
        "qd": traj.qd.tolist(),
        "qdd": traj.qdd.tolist(),
        "jerk": None if traj.jerk is None else traj.jerk.tolist(),
    }
    return json.dumps(payload, separators=(",", ":")) + "\n"


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def read_trajectory(path: str | Path) -> TimedTrajectory:
    """A trajectory from a CSV or JSON file written by this module (ExecutionError saying
    what is missing or malformed)."""
    source = Path(path)
    if not source.is_file():
        raise ExecutionError(f"trajectory file {source} does not exist")
    if source.suffix == ".csv":
        return _read_csv(source)
    if source.suffix == ".json":
        return _read_json(source)
    raise ExecutionError(f"{source}: a trajectory must be a .csv or .json file")


def _read_csv(source: Path) -> TimedTrajectory:
    header, data = read_csv_table(source)
    if not header or header[0] != "t":
        raise ExecutionError(f"{source}: the first column must be 't' (s), got {header[:1]}")
    names = [h[: -len("_pos")] for h in header if h.endswith("_pos")]
    if not names:
        raise ExecutionError(f"{source}: no '<joint>_pos' columns")

    def block(suffix: str) -> Array | None:
        cols = [f"{n}_{suffix}" for n in names]
        missing = [c for c in cols if c not in header]
        if len(missing) == len(cols) and suffix == "jerk":
            return None
        if missing:
            raise ExecutionError(f"{source}: missing columns {missing}")
        return data[:, [header.index(c) for c in cols]]

    t = data[:, 0]
    q, qd, qdd = (block(s) for s in ("pos", "vel", "acc"))
    if q is None or qd is None or qdd is None:  # unreachable: block raises for these
        raise ExecutionError(f"{source}: missing position, velocity or acceleration columns")
    return _make(
        source,
        t=t,
        q=q,
        qd=qd,
        qdd=qdd,
        jerk=block("jerk"),
        joint_names=tuple(names),
        rate_hz=_rate(t, source),
    )


#: rad/s, rad/s^2: a trajectory for a controller ends at rest
_REST = 1e-6


def _make(source: Path, **fields: Any) -> TimedTrajectory:
    try:
        traj = TimedTrajectory(**fields)
    except TimingError as err:
        raise ExecutionError(f"{source}: {err}") from err
    moving = np.flatnonzero((np.abs(traj.qd[-1]) > _REST) | (np.abs(traj.qdd[-1]) > _REST))
    if moving.size:
        j = int(moving[0])
        raise ExecutionError(
            f"{source}: the trajectory ends moving ({traj.joint_names[j]} at "
            f"{traj.qd[-1, j]:.3g} rad/s, {traj.qdd[-1, j]:.3g} rad/s^2 at t = {traj.t[-1]:.3f} s): "
            "the file is cut short, or not a whole trajectory (one ends at rest)"
        )
    return traj


def read_csv_table(source: Path) -> tuple[list[str], Array]:
    """Header names and the (N, C) float rows of a CSV file with one header row."""
    try:
        with source.open(newline="") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as err:
        raise ExecutionError(f"{source}: cannot be read as CSV ({err})") from err
    if len(rows) < 2:
        raise ExecutionError(f"{source}: needs a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    for line, row in enumerate(rows[1:], start=2):
        if row and len(row) != len(header):
            raise ExecutionError(
                f"{source}: line {line} has {len(row)} values; every row needs "
                f"{len(header)} values, as the header"
            )
    try:
        data = np.array([[float(v) for v in row] for row in rows[1:] if row], dtype=float)
    except ValueError as err:
        raise ExecutionError(f"{source}: a value is not a number ({err})") from err
    if data.ndim != 2:  # blank lines alone
        raise ExecutionError(f"{source}: needs a header row and at least one data row")
    if not np.all(np.isfinite(data)):
        raise ExecutionError(f"{source}: contains NaN or inf")
    return header, data


def _rate(t: Array, source: Path) -> float:
    if len(t) < 2:
        raise ExecutionError(f"{source}: needs at least 2 samples")
    dt = np.diff(t)
    step = float(np.median(dt))
    if step <= 0 or np.any(np.abs(dt - step) > 1e-6 + 1e-3 * step):
        raise ExecutionError(
            f"{source}: 't' must increase in equal steps (the controller rate); steps range "
            f"{dt.min():.6g} .. {dt.max():.6g} s"
        )
    return round(1.0 / step, 6)


def _read_json(source: Path) -> TimedTrajectory:
    raw = load_json(source, "trajectory file", ExecutionError)
    if not isinstance(raw, dict) or raw.get("format") != FORMAT:
        raise ExecutionError(f"{source}: not a trajectory file (needs format '{FORMAT}')")
    try:
        names = tuple(str(n) for n in raw["joint_names"])
        t = np.asarray(raw["t"], float)
        arrays = {k: np.asarray(raw[k], float) for k in ("q", "qd", "qdd")}
        jerk = None if raw.get("jerk") is None else np.asarray(raw["jerk"], float)
        limits = None if raw.get("limits") is None else _limits(raw["limits"])
        mode = None if raw.get("mode") is None else TimingMode(raw["mode"])
        status = TimingStatus(raw.get("status", "success"))
        path = None if raw.get("path") is None else np.asarray(raw["path"], float)
        segments = tuple(
            SegmentInfo(
                kind=str(s["kind"]),
                index=int(s["index"]),
                start_s=float(s["start_s"]),
                duration_s=float(s["duration_s"]),
            )
            for s in raw.get("segments", [])
        )
        figures = {str(k): float(v) for k, v in raw.get("figures", {}).items() if v is not None}
        notes = tuple(str(n) for n in raw.get("notes", []))
    except (KeyError, TypeError, ValueError, TimingError) as err:
        raise ExecutionError(f"{source}: malformed trajectory ({err!r})") from err
    return _make(
        source,
        t=t,
        q=arrays["q"],
        qd=arrays["qd"],
        qdd=arrays["qdd"],
        jerk=jerk,
        joint_names=names,
        rate_hz=float(raw.get("rate_hz") or _rate(t, source)),
        mode=mode,
        status=status,
        path=path,
        segments=segments,
        limits=limits,
        figures=figures,
        notes=notes,
    )


def _limits(raw: dict[str, Any]) -> JointLimits:
    return JointLimits(
        names=tuple(str(n) for n in raw["names"]),
        **{
            k: np.asarray(raw[k], float)
            for k in ("lower", "upper", "velocity", "acceleration", "jerk")
        },
    )
