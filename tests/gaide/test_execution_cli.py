from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml

from execution.joint_log import read_log_csv
from execution.trajectory_io import read_trajectory
from planning.robot_model import RobotModel
from tests.conftest import run_cli

OFFSETS = [
    [0, 0, 0, 0, 0, 0],
    [0.9, 0.2, -0.3, 0.0, 0.4, 0.0],
    [1.2, 0.5, -0.6, 0.3, 0.2, 0.8],
    [0.4, 0.6, -0.2, 0.5, -0.3, 1.0],
]


def _path_file(tmp_path: Path, robot: RobotModel, path: np.ndarray, scene: str) -> Path:
    out = tmp_path / "path.json"
    out.write_text(
        json.dumps(
            {
                "planner": "test",
                "status": "success",
                "scene": scene,
                "joint_names": list(robot.joint_names),
                "path": path.tolist(),
            }
        )
    )
    return out


def test_time_simulate_and_compare(tmp_path: Path, robot: RobotModel) -> None:
    path = robot.named_configuration("home") + np.array(OFFSETS)
    src = _path_file(tmp_path, robot, path, "none")
    traj, bag, png = tmp_path / "traj.csv", tmp_path / "traj.bag", tmp_path / "traj.png"
    proc = run_cli("time", str(src), "-o", str(traj), "-o", str(bag), "--plot", str(png))
    assert proc.returncode == 0, proc.stderr
    assert "blended" in proc.stdout and "limit violations" in proc.stdout
    timed = read_trajectory(traj)
    assert timed.rate_hz == 500.0
    np.testing.assert_allclose(timed.q[-1], path[-1], atol=1e-9)
    assert bag.stat().st_size > 10_000 and png.read_bytes().startswith(b"\x89PNG")

    log_bag, log_csv, report = tmp_path / "log.bag", tmp_path / "log.csv", tmp_path / "sim.json"
    proc = run_cli(
        "simulate", str(traj), "--log", str(log_bag), "--log", str(log_csv), "--json", str(report)
    )
    assert proc.returncode == 0, proc.stderr
    sim = json.loads(report.read_text())
    assert sim["status"] == "clear" and sim["rms_all_rad"] < 1e-3
    assert len(read_log_csv(log_csv).t) == len(timed.t)

    out = tmp_path / "cmp.json"
    proc = run_cli("compare", str(traj), str(log_bag), "--json", str(out))
    assert proc.returncode == 0, proc.stderr
    cmp = json.loads(out.read_text())
    assert abs(cmp["delay_s"]) <= 1.0 / 500.0 and cmp["rms_all_rad"] < 1e-3


def test_bad_input_exits_with_the_stage_code_and_writes_nothing(
    tmp_path: Path, robot: RobotModel
) -> None:
    # A problem file whose only obstacle sits on edge 1 of the path (at the hand, where the
    # shoulder swing of that edge passes through home).
    home = robot.named_configuration("home")
    offsets = [[-1.2, 0.3, 0, 0, 0, 0], [-1.2, 0, 0, 0, 0, 0], [1.2, 0, 0, 0, 0, 0]]
    path = home + np.array([*offsets, [1.2, 0.3, 0, 0, 0, 0]])
    from planning.checker import make_checker
    from planning.sphere_model import SphereModel

    assert robot.config.spheres is not None
    hand = make_checker(robot, SphereModel.load(robot.config.spheres)).sphere_centers(home[None])[
        0
    ][-1]
    problems = tmp_path / "scene.yaml"
    problems.write_text(
        yaml.safe_dump(
            {
                "problems": [
                    {
                        "name": "blocked",
                        "start": path[0].tolist(),
                        "goal": path[-1].tolist(),
                        "obstacles": [{"type": "sphere", "radius": 0.03, "center": hand.tolist()}],
                    }
                ]
            }
        )
    )
    src = _path_file(tmp_path, robot, path, str(problems))
    out = tmp_path / "out.csv"
    proc = run_cli("time", str(src), "-o", str(out), "--plot", str(tmp_path / "p.png"))
    assert proc.returncode == 8, proc.stderr
    assert proc.stderr.strip().count("\n") == 0
    assert "gaide time: error: edge 1 (waypoint 1 -> 2) collides" in proc.stderr
    assert not out.exists() and not (tmp_path / "p.png").exists()

    # A log that never overlaps the plan's expected start.
    good = _path_file(tmp_path, robot, home + np.array(OFFSETS), "none")
    traj = tmp_path / "traj.json"
    assert run_cli("time", str(good), "-o", str(traj), "--rate", "100").returncode == 0
    log = tmp_path / "log.csv"
    assert run_cli("simulate", str(traj), "--log", str(log)).returncode == 0
    plot = tmp_path / "cmp.png"
    proc = run_cli(
        "compare", str(traj), str(log), "--expected-start", "50", "--max-delay", "1",
        "--plot", str(plot),
    )  # fmt: skip
    assert proc.returncode == 9
    assert "shares no time with the plan" in proc.stderr
    assert not plot.exists()


def test_bench_timing_writes_every_key(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    proc = run_cli("bench", "timing", "--paths", "2", "--json", str(out))
    assert proc.returncode == 0, proc.stderr
    figures = json.loads(out.read_text())
    for key in (
        "limit_violations",
        "exact_path_dev_rad",
        "blended_over_exact_duration",
        "blended_collisions",
        "ms_per_path",
        "sim_tracking_rms_rad",
    ):
        assert key in figures
    assert figures["n_paths"] == 2 and figures["limit_violations"] == 0
    assert figures["exact_path_dev_rad"] <= 1e-6 and figures["blended_collisions"] == 0
    assert "ms_per_path" in proc.stdout
