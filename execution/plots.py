"""Pictures (PNG, matplotlib's Agg backend) of a timed trajectory and of a comparison."""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from execution.compare import CompareResult
from execution.limits import JointLimits
from execution.trajectory import TimedTrajectory
from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import ExecutionError


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def plot_trajectory(
    traj: TimedTrajectory, path: str | Path, limits: JointLimits | None = None
) -> Path:
    """Write :func:`trajectory_png` to ``path`` (atomically)."""
    return write_bytes_atomic(path, trajectory_png(traj, limits), ExecutionError)


def plot_comparison(result: CompareResult, path: str | Path) -> Path:
    """Write :func:`comparison_png` to ``path`` (atomically)."""
    return write_bytes_atomic(path, comparison_png(result), ExecutionError)


def trajectory_png(traj: TimedTrajectory, limits: JointLimits | None = None) -> bytes:
    """PNG of position, velocity, acceleration and jerk of every joint against time, each joint's
    limits dashed in its colour. Jerk is the trajectory's own, or the finite difference of
    its accelerations when it has none."""
    lim = limits or traj.limits
    jerk = traj.jerk if traj.jerk is not None else np.gradient(traj.qdd, traj.t, axis=0)
    rows = (
        ("position (rad)", traj.q, None if lim is None else (lim.lower, lim.upper)),
        ("velocity (rad/s)", traj.qd, None if lim is None else (-lim.velocity, lim.velocity)),
        (
            "acceleration (rad/s²)",
            traj.qdd,
            None if lim is None else (-lim.acceleration, lim.acceleration),
        ),
        ("jerk (rad/s³)", jerk, None if lim is None else (-lim.jerk, lim.jerk)),
    )
    fig, axes = plt.subplots(4, 1, figsize=(10, 11), sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (label, values, bounds) in zip(axes, rows, strict=True):
        for j, name in enumerate(traj.joint_names):
            colour = colours[j % len(colours)]
            ax.plot(traj.t, values[:, j], color=colour, lw=1.2, label=name)
            if bounds is not None:
                for b in (bounds[0][j], bounds[1][j]):
                    ax.axhline(b, color=colour, ls="--", lw=0.7, alpha=0.7)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=7, ncol=3)
    axes[-1].set_xlabel("t (s)")
    mode = traj.mode.value if traj.mode is not None else "trajectory"
    axes[0].set_title(f"{mode}: {traj.duration:.3f} s at {traj.rate_hz:g} Hz (dashed: limits)")
    fig.tight_layout()
    return _png(fig)


def comparison_png(result: CompareResult) -> bytes:
    """PNG of planned (solid) and logged (dotted) positions per joint after alignment, and the
    tracking error."""
    fig, axes = plt.subplots(2, 1, figsize=(10, 8), sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, name in enumerate(result.joint_names):
        colour = colours[j % len(colours)]
        axes[0].plot(result.t, result.planned[:, j], color=colour, lw=1.2, label=name)
        axes[0].plot(result.t, result.logged[:, j], color=colour, lw=1.2, ls=":")
        axes[1].plot(result.t, 1e3 * result.error[:, j], color=colour, lw=1.0, label=name)
    axes[0].set_ylabel("position (rad)")
    axes[0].legend(loc="upper right", fontsize=7, ncol=3)
    axes[0].set_title(
        f"plan (solid) vs log (dotted), log delayed {1e3 * result.delay_s:.1f} ms "
        f"(correlation {result.correlation:.3f})"
    )
    axes[1].set_ylabel("log - plan (mrad)")
    axes[1].set_xlabel("plan time (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return _png(fig)
