from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import yaml

from execution.joint_log import read_log_csv
from execution.ruckig_timing import RuckigParameterizer
from execution.timing_cfg import TimingCfg, TimingMode
from execution.trajectory import TimedTrajectory
from execution.trajectory_io import read_trajectory, trajectory_csv
from execution.urscript import UrScriptMode
from gaide.pipeline.config import ExportCfg, RunCfg
from gaide.pipeline.execute import export_stage
from gaide.pipeline.runner import StageRunner
from planning.checker import make_checker
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel
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


def test_a_path_file_finds_its_scene_file_beside_it(tmp_path: Path, robot: RobotModel) -> None:
    # `gaide run` and `gaide plan` name the scene file relative to the path file's folder, so
    # `gaide time` finds it from any working directory (here the repository root, where no
    # such file is) and the folder can move.
    path = robot.named_configuration("home") + np.array(OFFSETS)
    q = [float(v) for v in path[0]]
    problem = {"problems": [{"name": "cell", "start": q, "goal": q, "obstacles": []}]}
    (tmp_path / "cell.yaml").write_text(yaml.safe_dump(problem))
    src = _path_file(tmp_path, robot, path, "cell.yaml")
    proc = run_cli("time", str(src), "-o", str(tmp_path / "t.csv"))
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "t.csv").is_file()


def test_relative_scene_names_round_trip() -> None:
    from gaide.scene_spec import next_to, relative_to

    assert relative_to("tabletop seed 3", "/a/b") == "tabletop seed 3"
    assert relative_to("/a/c/scene.ply", "/a/b") == "../c/scene.ply"
    assert relative_to("/a/b/cell.yaml#first", "/a/b") == "cell.yaml#first"
    assert next_to("none", "/a/b") == "none"
    assert next_to("/abs/scene.ply", "/a/b") == "/abs/scene.ply"
    # a relative file that is not beside the path file stays as written (the working
    # directory's, as older path files name it)
    assert next_to("out/demo/scene.ply", "/nonexistent") == "out/demo/scene.ply"


def test_time_simulate_and_compare(tmp_path: Path, robot: RobotModel) -> None:
    path = robot.named_configuration("home") + np.array(OFFSETS)
    src = _path_file(tmp_path, robot, path, "none")
    traj, bag, png = tmp_path / "traj.csv", tmp_path / "traj.bag", tmp_path / "traj.png"
    script, goal = tmp_path / "x.script", tmp_path / "g.yaml"
    proc = run_cli(
        "time", str(src), "-o", str(traj), "-o", str(bag), "-o", str(script), "-o", str(goal),
        "--plot", str(png),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "blended" in proc.stdout and "limit violations" in proc.stdout
    timed = read_trajectory(traj)
    assert timed.rate_hz == 500.0
    np.testing.assert_allclose(timed.q[-1], path[-1], atol=1e-9)
    assert bag.stat().st_size > 10_000 and png.read_bytes().startswith(b"\x89PNG")
    # a servoj per sample at 2 ms, ending at the goal
    program = script.read_text()
    targets = re.findall(r"^  servoj\(\[([^\]]*)\], 0, 0, 0\.002, 0\.03, 2000\.0\)$", program, re.M)
    assert len(targets) == len(timed.t)
    np.testing.assert_allclose([float(v) for v in targets[-1].split(",")], path[-1], atol=5e-11)
    assert program.endswith("end\ngaide_trajectory()\n")
    # the goal, ready for `ros2 action send_goal` (its first line says how)
    text = goal.read_text()
    assert text.startswith("# ros2 action send_goal /joint_trajectory_controller/")
    assert text.splitlines()[0].endswith('"$(cat g.yaml)"')
    points = yaml.safe_load(text)["trajectory"]["points"]
    n = len(timed.t)
    assert len(points) == len(range(0, n, 10)) + ((n - 1) % 10 != 0)  # 50 Hz, and the end
    np.testing.assert_allclose(points[-1]["positions"], path[-1], atol=1e-9)

    log_bag, log_csv, report = tmp_path / "log.bag", tmp_path / "log.csv", tmp_path / "sim.json"
    proc = run_cli(
        "simulate", str(traj), "--log", str(log_bag), "--log", str(log_csv), "--json", str(report)
    )
    assert proc.returncode == 0, proc.stderr
    sim = json.loads(report.read_text())
    assert sim["status"] == "clear" and sim["controller"] == "servo"
    assert sim["rms_all_rad"] < 0.01 and sim["rms_after_delay_all_rad"] < 1e-3
    # the servo's 3-cycle delay, then the goal held for the run's settle_s (0.2 s at 500 Hz)
    assert len(read_log_csv(log_csv).t) == len(timed.t) + 3 + 100

    out = tmp_path / "cmp.json"
    proc = run_cli("compare", str(traj), str(log_bag), "--json", str(out))
    assert proc.returncode == 0, proc.stderr
    cmp = json.loads(out.read_text())
    assert abs(cmp["delay_s"] - sim["delay_s"]) <= 1e-3 and cmp["rms_all_rad"] < 1e-3


def test_bad_input_exits_with_the_stage_code_and_writes_nothing(
    tmp_path: Path, robot: RobotModel
) -> None:
    # A problem file whose only obstacle sits on edge 1 of the path (at the hand, where the
    # shoulder swing of that edge passes through home).
    home = robot.named_configuration("home")
    offsets = [[-1.2, 0.3, 0, 0, 0, 0], [-1.2, 0, 0, 0, 0, 0], [1.2, 0, 0, 0, 0, 0]]
    path = home + np.array([*offsets, [1.2, 0.3, 0, 0, 0, 0]])

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


def test_an_unknown_format_or_another_robots_trajectory_exits_9_writing_nothing(
    tmp_path: Path, robot: RobotModel
) -> None:
    src = _path_file(tmp_path, robot, robot.named_configuration("home") + np.array(OFFSETS), "none")
    good, bad = tmp_path / "t.csv", tmp_path / "x.txt"
    proc = run_cli("time", str(src), "-o", str(good), "-o", str(bad))
    assert proc.returncode == 9, proc.stderr
    assert proc.stderr.strip().count("\n") == 0
    assert "x.txt: unknown output format '.txt'; valid: .csv, .json" in proc.stderr
    assert ".script (URScript)" in proc.stderr and ".yaml/.yml" in proc.stderr
    assert not good.exists() and not bad.exists()

    # A trajectory of other joints than the robot's, replayed on the robot.
    names = ("a", "b", "c", "d", "e", "f")
    other = TimedTrajectory(
        t=np.array([0.0, 0.01]), q=np.zeros((2, 6)), qd=np.zeros((2, 6)), qdd=np.zeros((2, 6)),
        joint_names=names, rate_hz=100.0,
    )  # fmt: skip
    traj = tmp_path / "other.csv"
    traj.write_text(trajectory_csv(other))
    log = tmp_path / "log.csv"
    proc = run_cli("simulate", str(traj), "--log", str(log))
    assert proc.returncode == 9, proc.stderr
    assert proc.stderr.strip().count("\n") == 0
    assert "joints ['a', 'b', 'c', 'd', 'e', 'f'] are not the robot's" in proc.stderr
    assert not log.exists()


def test_the_run_exports_the_formats_asked_for(
    tmp_path: Path, robot: RobotModel, spheres: SphereModel
) -> None:
    path = robot.named_configuration("home") + np.array(OFFSETS)
    timing = TimingCfg(rate_hz=100.0, mode=TimingMode.EXACT, shortcut=False)
    traj = RuckigParameterizer(timing).parameterize(path, make_checker(robot, spheres))
    export = ExportCfg(formats=("csv", "urscript", "ros2_goal"), urscript_mode=UrScriptMode.MOVEJ)
    runner = StageRunner(tmp_path, ["export"])
    written = export_stage(RunCfg(export=export), traj, runner, runner.records["export"])
    assert [p.name for p in written] == [
        "trajectory.csv",
        "trajectory.script",
        "trajectory_goal.yaml",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in written)
    program = (tmp_path / "trajectory.script").read_text()
    assert program.count("  movej(") == len(path) and "servoj" not in program
    goal = yaml.safe_load((tmp_path / "trajectory_goal.yaml").read_text())
    assert goal["trajectory"]["joint_names"] == list(robot.joint_names)


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
