from __future__ import annotations

import json
from pathlib import Path

import pytest

from gaide.common import JobProgress
from tests.conftest import run_cli


def test_bench_collision_quick_writes_every_key(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    proc = run_cli("bench", "collision", "--quick", "--json", str(out))
    assert proc.returncode == 0, proc.stderr
    figures = json.loads(out.read_text())
    for key in (
        "configs_per_s_cloud",
        "configs_per_s_primitives",
        "edges_per_s",
        "fk_max_err_m",
        "mesh_missed",
        "mesh_false_alarm_rate",
    ):
        assert key in figures
    assert figures["fk_max_err_m"] <= 1e-9
    assert figures["mesh_missed"] == 0
    assert figures["machine"]["cores"] >= 1 and figures["machine"]["cpu"]
    assert "configs_per_s_cloud" in proc.stdout and "cores, numba" in proc.stdout
    # stderr is a pipe here, as in a CI log: no progress bar's carriage-return redraws
    assert "mesh reference" not in proc.stderr and "\r" not in proc.stderr


def test_bad_input_prints_one_line_and_exits_with_the_stage_code(tmp_path: Path) -> None:
    proc = run_cli("robot", "show", "--q", "1,2", "-o", str(tmp_path / "x.png"))
    assert proc.returncode == 6
    assert proc.stderr.strip().count("\n") == 0
    assert "has 2 values; the robot has 6 joints" in proc.stderr
    assert not (tmp_path / "x.png").exists()
    cfg = tmp_path / "robot.yaml"
    cfg.write_text(f"urdf: {tmp_path / 'missing.urdf'}\n")
    proc = run_cli("robot", "info", "--robot", str(cfg))
    assert proc.returncode == 6 and "missing.urdf does not exist" in proc.stderr


def test_a_long_job_off_a_terminal_logs_plain_lines(capsys: pytest.CaptureFixture[str]) -> None:
    # stderr is captured here, as in `nohup gaide train ... > log`: no bar, a line per 1/4
    bar = JobProgress("train gaide", "step", total=100, lines=4)
    for step in range(10, 101, 10):
        bar.update(step, val="0.0100")
    bar.update(100, val="0.0100")  # the end once more: nothing new to say
    bar.close()
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.splitlines()
    assert [line.split(",")[0] for line in lines] == [
        "train gaide: 30/100 steps (30%)",
        "train gaide: 50/100 steps (50%)",
        "train gaide: 80/100 steps (80%)",
        "train gaide: 100/100 steps (100%)",
    ]
    assert all(", val=0.0100, " in line and line.endswith(" s") for line in lines)

    # a total known only once the job has started (data generation's shards)
    shards = JobProgress("gaide data generate", "shard")
    shards.update(1, 2)
    shards.update(2, 2)
    assert (
        capsys.readouterr()
        .err.splitlines()[-1]
        .startswith("gaide data generate: 2/2 shards (100%)")
    )
