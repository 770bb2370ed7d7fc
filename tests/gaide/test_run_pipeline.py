"""`gaide run` and `gaide demo` end to end, each stage's failure, the report, the settings.

One successful run on a small synthetic bag (a subprocess) is shared by the assertions on
outputs and the report; the failure paths run in-process through the CLI's ``main`` (same
code path, without paying the imports again).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from gaide.cli import main
from gaide.pipeline.config_io import effective_dict, load_cfg
from gaide.pipeline.endpoints import EndpointKind, parse_endpoint
from gaide.pipeline.run import STAGES
from gaide_core.errors import ConfigError
from planning.robot_config import example_robot_data_share
from planning.robot_model import RobotModel
from tests.conftest import ROOT, run_cli, shared_data
from tests.gaide.conftest import GOAL, RUN_FLAGS

PICTURES = ("calibration_overlay.png", "scene.png", "path.png", "trajectory.png", "tracking.png")
OUTPUTS = (
    "calibration.yaml",
    "scene.ply",
    "plan.json",
    "trajectory.csv",
    "trajectory.json",
    "trajectory.bag",
    "sim_log.csv",
    "simulation.json",
    "report.html",
    "summary.json",
    *PICTURES,
)
# The exact command of the README's "your own recording without a tag" section.
REAL_BAG = "../shared/data/realsense/librealsense_single_depth_color_640x480.bag"
REAL_ARGS = (
    "--T-base-cam=-0.7,-0.3,0.7,0.6517,-0.4994,0.3473,-0.4531",
    "--start",
    "home",
    "--goal",
    "xyz:0.3,0.4,0.35",
)


def _leftovers(out: Path) -> list[str]:
    """Temporary files or folders a write left behind."""
    return [p.name for p in out.iterdir() if p.name.startswith(".") or ".tmp" in p.name]


def test_run_writes_every_stage_output_and_a_summary(run_out: tuple[Path, str]) -> None:
    out, stdout = run_out
    for name in OUTPUTS:
        assert (out / name).stat().st_size > 100, name
    assert not _leftovers(out)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "success" and summary["failed_stage"] is None
    assert [s["status"] for s in summary["stages"].values()] == ["success"] * len(STAGES)
    st = summary["stages"]
    assert st["calibration"]["figures"]["reprojection_rms_px"] < 0.5
    assert st["perception"]["figures"]["points"] > 5000
    assert st["planning"]["figures"]["attempts"] >= 1
    assert st["timing"]["figures"]["limit_violations"] == 0
    sim = st["simulation"]["figures"]
    assert sim["tracking_rms_after_delay_rad"] < 0.01 and sim["tracking_rms_rad"] < 0.05
    assert sim["precheck_invalid_samples"] == 0 and sim["executed_clearance_ok"] is True
    # the summary table names each figure and where each file is
    for text in ("RMS", "points", "attempt", "rad", "Hz", "tracking", str(out / "report.html")):
        assert text in stdout, text


def test_run_plans_from_the_recorded_state_to_the_pose_goal(
    run_out: tuple[Path, str], robot: RobotModel
) -> None:
    out, _ = run_out
    plan = json.loads((out / "plan.json").read_text())
    path = np.asarray(plan["path"])
    np.testing.assert_allclose(path[0], robot.named_configuration("home"), atol=1e-6)
    goal_xyz = robot.frame_pose(path[-1])[:3, 3]
    np.testing.assert_allclose(goal_xyz, [0.45, -0.1, 0.25], atol=1e-3)
    from execution.trajectory_io import read_trajectory

    traj = read_trajectory(out / "trajectory.csv")
    np.testing.assert_allclose(traj.q[0], path[0], atol=1e-6)
    np.testing.assert_allclose(traj.q[-1], path[-1], atol=1e-6)
    assert traj.rate_hz == pytest.approx(100.0)


def test_report_is_self_contained_and_shows_every_picture(run_out: tuple[Path, str]) -> None:
    out, _ = run_out
    page = (out / "report.html").read_text()
    # the page's own markup: plotly.js, inline, holds URLs and data URIs in its code
    markup = re.sub(r"<script\b.*?</script>", "", page, flags=re.S)
    for name in PICTURES:
        assert name in markup, name
    assert markup.count('src="data:image/png;base64,') == len(PICTURES)
    assert not re.search(r"""(src|href)=["']?https?:""", markup)  # nothing to fetch
    assert "Every stage succeeded" in page and "tracking RMS" in page


def _run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    code = main(["run", *args])
    return code, capsys.readouterr().err.strip().splitlines()[-1]


FAILURES = {
    # name: (extra args, exit code, failed stage, text in the message)
    "no-target": ((), 4, "calibration", "found in 0 of 2 images"),
    "empty-cloud": (
        ("--set", "perception.workspace_min=[5,5,5]", "--set", "perception.workspace_max=[6,6,6]"),
        5,
        "perception",
        "workspace box",
    ),
    "start-in-collision": (
        ("--start", "0,0.5,0,0,0,0"),
        7,
        "planning",
        "links in collision with the world",
    ),
    "no-path-in-budget": (("--budget", "1e-4", "--attempts", "2"), 7, "planning", "no path"),
    "limits": (("--set", "timing.max_velocity=[1,1,1]"), 8, "timing", "velocity"),
    "tracking": (("--set", "simulate.max_tracking_rms_rad=1e-12"), 9, "simulation", "RMS"),
}


@pytest.mark.parametrize("case", list(FAILURES))
def test_a_failed_stage_exits_with_its_code_and_keeps_earlier_outputs(
    case: str,
    bag: Path,
    run_out: tuple[Path, str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    extra, code, stage, text = FAILURES[case]
    out = tmp_path / "out"
    produced = {
        "calibration": "calibration_overlay.png",
        "perception": "scene.ply",
        "planning": "plan.json",
        "timing": "trajectory.png",
        "simulation": "sim_log.csv",
    }[stage]
    out.mkdir()
    # an earlier run's file, listed in its summary as a run lists what it wrote: it must not
    # survive this run
    (out / produced).write_text("from an earlier run")
    earlier = {"stages": {"setup": {"outputs": [str(out / produced)]}}}
    (out / "summary.json").write_text(json.dumps(earlier))
    source: tuple[str, ...] = ("--calib", str(run_out[0] / "calibration.yaml"))
    if case == "no-target":
        wrong = tmp_path / "wrong_target.yaml"
        pose = yaml.safe_load((bag.parent / "cell.target_pose.yaml").read_text())
        pose["target"] = "tag36h11:id=300,size=0.08"
        wrong.write_text(yaml.safe_dump(pose))
        source = ("--target-pose", str(wrong))
    rc, line = _run(capsys, str(bag), "--goal", GOAL, "-o", str(out), *RUN_FLAGS, *source, *extra)
    assert rc == code, line
    assert line.startswith(f"gaide run: error: {stage}: ") and text in line, line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failed_stage"] == stage and summary["status"] == "failed"
    index = STAGES.index(stage)
    for name in STAGES[1:index]:  # every earlier stage's files are there, whole
        record = summary["stages"][name]
        assert record["status"] == "success", name
        for path in record["outputs"]:
            assert Path(path).stat().st_size > 0, path
    assert summary["stages"][stage]["outputs"] == []
    assert not (out / produced).exists()
    assert not _leftovers(out)
    assert "Failed at stage" in (out / "report.html").read_text()


def test_settings_errors_exit_2_naming_the_key(
    bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc, line = _run(capsys, str(bag), "--goal", GOAL, "--set", "planning.bugdet_s=3")
    assert rc == 2 and "planning.bugdet_s" in line and "budget_s" in line
    rc, line = _run(capsys, str(bag), "--goal", GOAL, "--set", "timing.rate_hz=0")
    assert rc == 2 and "timing.rate_hz" in line and "[1, 2000]" in line
    rc, line = _run(capsys, str(bag), "-o", str(tmp_path / "o"), "--goal", "1,2")
    assert rc == 2 and "6 joints" in line
    rc, line = _run(capsys, str(bag), "-o", str(tmp_path / "o"), "--goal", "home", "--planner",
                    "gaide-hybrid", "--checkpoint", str(tmp_path / "missing.pt"))  # fmt: skip
    assert rc == 10 and line.startswith("gaide run: error: setup: ") and "missing.pt" in line


def test_settings_precedence_defaults_then_file_then_flags(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg_file = tmp_path / "mine.yaml"
    cfg_file.write_text(
        "bag: rec/cell.bag\nplanning: {budget_s: 3.0, goal: home}\ntiming: {rate_hz: 250}\n"
    )
    assert main(["config", "show", "--config", str(cfg_file), "--budget", "7"]) == 0
    shown = yaml.safe_load(capsys.readouterr().out)
    assert shown["planning"]["budget_s"] == 7.0  # flag over file
    assert shown["timing"]["rate_hz"] == 250.0  # file over default
    assert shown["planning"]["attempts"] == effective_dict()["planning"]["attempts"]  # default
    assert shown["planning"]["goal"] == "home"
    assert shown["bag"] == str(tmp_path / "rec" / "cell.bag")  # relative to the file
    # a dedicated flag wins over --set; --set over the file
    cfg = load_cfg([cfg_file], [("planning.budget_s", 9.0), ("planning.budget_s", 4.0)])
    assert cfg.planning.budget_s == 4.0
    assert main(["config", "show", "--set", "planning.budget_s=5", "--budget", "6"]) == 0
    assert yaml.safe_load(capsys.readouterr().out)["planning"]["budget_s"] == 6.0
    # what `config show` prints is itself a valid settings file
    again = tmp_path / "again.yaml"
    assert main(["config", "show", "--config", str(cfg_file)]) == 0
    again.write_text(capsys.readouterr().out)
    assert load_cfg([again]) == load_cfg([cfg_file])
    # the timing section reaches the execution layer field for field
    timing = load_cfg([cfg_file], [("timing.mode", "exact")]).timing
    assert timing.rate_hz == 250.0 and timing.mode.value == "exact"


def test_a_settings_file_names_a_shipped_robot_or_its_own_file(tmp_path: Path) -> None:
    cfg_file = tmp_path / "mine.yaml"
    cfg_file.write_text("robot: panda\nperception: {bag_robot: ur10}\n")
    cfg = load_cfg([cfg_file])
    assert cfg.robot == "panda" and cfg.perception.bag_robot == "ur10"  # shipped names
    (tmp_path / "panda").write_text("urdf: arm.urdf\n")  # a file of that name beside it wins
    assert load_cfg([cfg_file]).robot == str(tmp_path / "panda")


def test_a_stage_reports_its_own_code_except_for_settings_bags_and_models() -> None:
    from gaide.pipeline.runner import stage_error
    from gaide_core.errors import BagError, ModelError, PerceptionError, PlanningError

    err = stage_error(PerceptionError("the scene cloud has 3 points"), "planning")
    assert type(err) is PlanningError and str(err) == "planning: the scene cloud has 3 points"
    for kept in (ConfigError("x"), BagError("x"), ModelError("x")):
        assert type(stage_error(kept, "perception")) is type(kept)


def test_endpoint_forms(robot: RobotModel) -> None:
    assert parse_endpoint("recorded", robot, "start").kind is EndpointKind.RECORDED
    home = parse_endpoint("home", robot, "start")
    assert home.kind is EndpointKind.NAMED and home.joints is not None
    joints = parse_endpoint("0,-1,1,-1,-1.5,0", robot, "goal")
    assert joints.kind is EndpointKind.JOINTS
    pose = parse_endpoint("pose:0.4,0,0.3,1,0,0,0", robot, "goal")
    assert pose.kind is EndpointKind.POSE and pose.quat_xyzw is not None
    xyz = parse_endpoint("xyz:0.4,0,0.3", robot, "goal")
    assert xyz.kind is EndpointKind.POSE and xyz.quat_xyzw is None
    for bad, match in (
        ("nowhere", "not a named configuration"),
        ("1,2,3", "6 joints"),
        ("xyz:1,2", "x,y,z"),
        ("pose:0,0,0,0,0,0,0", "unit quaternion"),
        ("joint:1,2", "unknown form"),
    ):
        with pytest.raises(ConfigError, match=match):
            parse_endpoint(bad, robot, "goal")


@pytest.mark.slow
def test_demo_runs_cold_on_the_shipped_bag(tmp_path: Path) -> None:
    proc = run_cli("demo", "--quick", "-o", str(tmp_path / "demo"))
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "demo"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "success"
    st = summary["stages"]
    assert st["planning"]["figures"]["planner"] == "gaide-hybrid"
    # the demo's goal is not reachable in a straight joint-space line
    assert not st["planning"]["figures"]["direct_edge_valid"]
    assert st["calibration"]["figures"]["reprojection_rms_px"] < 0.5
    # The certified path keeps the margin in the cloud's true distances, and the simulation's
    # report says so: the lattice's lower bound alone read 4 of its samples inside the margin
    # and the executed clearance as 4.0 mm (simulate.report_validity).
    sim = st["simulation"]["figures"]
    assert sim["precheck_invalid_samples"] == 0 and sim["executed_clearance_ok"] is True
    page = (out / "report.html").read_text()
    assert all(name in page for name in PICTURES)
    assert not _leftovers(out)
    # `gaide simulate` replays the run's trajectory as the run simulated it (the same boxes,
    # crop and servo): the same report. With the library's coarser 2 cm boxes and no crop it
    # had found a contact 13 mm from the cloud that the run had not.
    replay = tmp_path / "replay.json"
    trajectory, scene = str(out / "trajectory.csv"), str(out / "scene.ply")
    assert (
        main(["simulate", trajectory, "--scene", scene, "--settle", "0", "--json", str(replay)])
        == 0
    )
    ran = json.loads((out / "simulation.json").read_text())
    again = json.loads(replay.read_text())
    assert again["status"] == ran["status"] and again["contacts"] == ran["contacts"]
    for key in ("rms_all_rad", "max_all_rad", "executed_min_clearance_m"):  # the CSV's digits
        assert again[key] == pytest.approx(ran[key], rel=1e-4), key


def test_real_recording_runs_with_a_given_camera_pose(tmp_path: Path) -> None:
    shared_data("realsense/librealsense_single_depth_color_640x480.bag")
    readme = (ROOT / "README.md").read_text()
    command = " ".join(("gaide run", REAL_BAG, *REAL_ARGS))
    assert command in readme, "the README shows this exact command"
    out = tmp_path / "real"
    proc = subprocess.run(
        [sys.executable, "-m", "gaide", "run", REAL_BAG, *REAL_ARGS, "-o", str(out)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    st = summary["stages"]
    assert st["calibration"]["status"] == "skipped"
    assert st["perception"]["figures"]["points"] > 5000
    assert st["planning"]["status"] == "success"
    assert st["timing"]["figures"]["duration_s"] > 0
    for name in ("scene.ply", "plan.json", "trajectory.csv", "report.html"):
        assert (out / name).is_file(), name


def test_a_run_replaces_only_what_runs_wrote_and_one_runs_at_a_time(
    bag: Path, run_out: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import subprocess
    import sys

    calib = ("--calib", str(run_out[0] / "calibration.yaml"))
    out = tmp_path / "mine"
    out.mkdir()
    # the user's own files under names a run writes: refused, untouched
    (out / "plan.json").write_text("my plan")
    (out / "trajectory_ros2").mkdir()
    (out / "trajectory_ros2" / "keep.txt").write_text("mine")
    rc, line = _run(capsys, str(bag), "--goal", GOAL, "-o", str(out), *RUN_FLAGS, *calib)
    assert rc == 2 and "no gaide run wrote there" in line and "plan.json" in line, line
    assert (out / "plan.json").read_text() == "my plan"
    assert (out / "trajectory_ros2" / "keep.txt").exists()
    assert sorted(p.name for p in out.iterdir()) == ["plan.json", "trajectory_ros2"]

    # a live process holding the folder's lock: refused; a stale lock: taken over
    free = tmp_path / "locked"
    free.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (free / ".gaide-run.lock").write_text(str(holder.pid))
        rc, line = _run(capsys, str(bag), "--goal", GOAL, "-o", str(free), *RUN_FLAGS, *calib)
        assert rc == 2 and f"process {holder.pid}" in line, line
        assert not (free / "summary.json").exists()
    finally:
        holder.kill()
        holder.wait()
    assert main(["run", str(bag), "--goal", GOAL, "-o", str(free), *RUN_FLAGS, *calib]) == 0
    assert not (free / ".gaide-run.lock").exists()
    assert json.loads((free / "summary.json").read_text())["status"] == "success"


def test_the_summary_says_running_until_the_run_ends(
    bag: Path, run_out: tuple[Path, str], tmp_path: Path
) -> None:
    from gaide.pipeline.config_io import load_cfg
    from gaide.pipeline.run import run_pipeline
    from gaide.pipeline.runner import StageRecord

    out = tmp_path / "watched"
    seen: list[str] = []

    class Watch:
        def started(self, name: str, index: int, total: int) -> None:
            if name == "timing":
                seen.append(json.loads((out / "summary.json").read_text())["status"])

        def finished(self, record: StageRecord) -> None:
            pass

    cfg = load_cfg(
        overrides=[
            ("bag", str(bag)), ("out", str(out)), ("planning.goal", GOAL),
            ("calibration.calib", str(run_out[0] / "calibration.yaml")),
            ("planning.planner", "rrtc"), ("timing.rate_hz", 100.0),
            ("simulate.settle_s", 0.0), ("report.enabled", False),
        ]
    )  # fmt: skip
    run_pipeline(cfg, hooks=Watch())
    assert seen == ["running"]
    assert json.loads((out / "summary.json").read_text())["status"] == "success"


@pytest.mark.slow
def test_a_robot_set_up_from_its_urdf_runs_the_demo(tmp_path: Path) -> None:
    """An xArm7 from its URDF alone (7 joints): setup, then the demo end to end with the
    xArm standing where the bag's UR5 stood (the UR5's points removed with its joints)."""
    share = example_robot_data_share()
    assert share is not None
    urdf = share / "example-robot-data" / "robots" / "xarm_description" / "urdf" / "xarm7.urdf"
    config = tmp_path / "xarm7.yaml"
    setup = ["robot", "setup", str(urdf), "--samples", "1000", "-o", str(config)]
    assert main(setup) == 0
    assert main(["demo", "--robot", str(config), "--quick", "-o", str(tmp_path / "d")]) == 0
    summary = json.loads((tmp_path / "d" / "summary.json").read_text())
    assert summary["status"] == "success"
    st = summary["stages"]
    assert st["setup"]["figures"]["dof"] == 7
    assert st["planning"]["figures"]["planner"] == "rrtc"
    assert st["perception"]["figures"]["self_filter"] is True
    assert st["simulation"]["figures"]["status"] == "clear"
    assert (tmp_path / "d" / "report.html").is_file()
