from __future__ import annotations

from pathlib import Path

from execution.compare import compare
from execution.plots import plot_comparison, plot_trajectory
from execution.trajectory import TimedTrajectory
from gaide_core.joints import JointStates

PNG = b"\x89PNG\r\n\x1a\n"


def test_trajectory_and_comparison_plots_are_pngs(
    small_traj: TimedTrajectory, tmp_path: Path
) -> None:
    out = plot_trajectory(small_traj, tmp_path / "traj.png")
    data = out.read_bytes()
    assert data.startswith(PNG) and len(data) > 20_000
    log = JointStates(names=small_traj.joint_names, t=small_traj.t + 3.0, q=small_traj.q)
    out = plot_comparison(compare(small_traj, log), tmp_path / "cmp.png")
    assert out.read_bytes().startswith(PNG)
