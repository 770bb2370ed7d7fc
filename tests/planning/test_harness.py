from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from gaide_core.errors import PlanningError
from planning import harness
from planning.checker import make_checker
from planning.families import generate_problem
from planning.family_names import split_seed
from planning.harness import HarnessCfg, run_harness
from planning.harness_report import markdown_table, text_table
from planning.neural.checkpoint import shipped_checkpoint
from planning.path_check import check_path
from planning.planner import PlanResult, PlanStatus
from planning.problem import save_problems
from planning.registry import make_planner
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel
from tests.conftest import run_cli


def test_a_planted_colliding_path_is_rejected_with_its_edge(
    robot: RobotModel, spheres: SphereModel
) -> None:
    p = generate_problem("box", split_seed("test", 0), robot, spheres)
    # straight through: start -> a configuration folded into the table -> goal
    through = np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0])
    path = np.stack([p.start, through, p.goal])
    check = check_path(path, p.start, p.goal, robot, spheres, p.world)
    assert not check.ok and check.bad_edge == 0
    assert "edge 0 of 2 collides" in check.detail and "world" in check.detail
    wrong_end = np.stack([p.start, p.start])
    assert (
        "does not start at the start and end at the goal"
        in check_path(wrong_end, p.start, p.goal, robot, spheres, p.world).detail
    )


def test_malformed_paths_are_rejected_by_name(robot: RobotModel, spheres: SphereModel) -> None:
    p = generate_problem("box", split_seed("test", 0), robot, spheres)

    def detail(path: np.ndarray | None, goal: np.ndarray = p.goal) -> str:
        check = check_path(path, p.start, goal, robot, spheres, p.world)
        assert not check.ok
        return check.detail

    assert detail(None) == "no path"
    assert detail(p.start[None]) == "no path"
    nan = np.stack([p.start, np.full(robot.dof, np.nan), p.goal])
    assert "non-finite" in detail(nan)
    assert "shape (2, 5)" in detail(np.stack([p.start, p.goal])[:, :5])
    assert "goals have shape (0, 6)" in detail(np.stack([p.start, p.goal]), np.zeros((0, 6)))


def test_a_valid_path_passes_the_mesh_check_too(robot: RobotModel, spheres: SphereModel) -> None:
    # The spheres cover the meshes, so a path the spheres pass keeps the meshes off the world:
    # PyBullet's mesh check, every 2 centiradians, agrees.
    p = generate_problem("box", split_seed("test", 0), robot, spheres)
    res = make_planner("rrtc").plan(
        make_checker(robot, spheres, p.world),
        p.start,
        p.goal,
        budget_s=60.0,
        rng=np.random.default_rng(0),
    )
    assert res.path is not None, res.detail
    check = check_path(res.path, p.start, p.goal, robot, spheres, p.world, meshes=True)
    assert check.ok, check.detail


def test_a_planner_returning_a_colliding_path_counts_as_a_failure(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    class Liar:
        name = "liar"

        def plan(self, checker, start, goal, *, budget_s, rng):  # type: ignore[no-untyped-def]
            bad = np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0])
            return PlanResult("liar", PlanStatus.SUCCESS, np.stack([start, bad, goal]), 0.01)

    harness._init_worker(None)
    monkeypatch.setattr(harness, "make_planner", lambda name, **_: Liar())
    rec = harness._run((("box", split_seed("test", 0), None), "liar", 1.0, False, "compiled"))
    assert rec.status == "bad_path" and not rec.success and rec.cost is None
    assert "collides" in rec.detail


def test_harness_runs_every_planner_on_the_same_problems(tmp_path: Path) -> None:
    cfg = HarnessCfg(
        families=("tabletop", "bins"),
        planners=("rrtconnect", "rrtstar"),
        problems=2,
        budget_s=0.5,
        workers=2,
    )
    result = run_harness(cfg)
    summary = result.summary()
    assert set(summary) == {"tabletop", "bins"}
    for fam in summary.values():
        assert set(fam) == {"rrtconnect", "rrtstar"}
        for fig in fam.values():
            assert fig["n"] == 2 and 0.0 <= fig["success_rate"] <= 1.0
            assert {"time_median_s", "time_mean_s", "cost_median", "success_rate", "n"} <= set(fig)
    problems = {(r.planner, r.problem) for r in result.records}
    assert len(problems) == 8  # 2 planners x 2 families x 2 problems, each once
    # anytime planners use their budget; RRT-Connect stops at its first solution
    star = [r.time_s for r in result.records if r.planner == "rrtstar"]
    assert min(star) >= 0.45
    assert "TableTop" in text_table(result) and "| rrtconnect |" in markdown_table(result)
    json.dumps(result.to_json())


def test_harness_budget_auto_without_reference_is_fixed() -> None:
    cfg = HarnessCfg(
        families=("tabletop",),
        planners=("rrtconnect",),
        problems=1,
        budget_s=None,
        fallback_budget_s=0.3,
        workers=1,
    )
    result = run_harness(cfg)
    assert result.budgets["tabletop"]["rrtconnect"] == 0.3
    assert "fixed 0.3 s" in result.notes[0]


def test_harness_bad_problems_are_counted_not_solved(
    robot: RobotModel, spheres: SphereModel, tmp_path: Path
) -> None:
    p = generate_problem("tabletop", split_seed("test", 1), robot, spheres)
    from dataclasses import replace

    folded = replace(p, name="bad-start", start=np.array([0.0, 0.3, 0.0, 0.0, 0.0, 0.0]))
    path = tmp_path / "problems.yaml"
    save_problems(path, [p, folded])
    result = run_harness(
        HarnessCfg(problem_file=path, planners=("rrtconnect",), budget_s=1.0, workers=1)
    )
    fig = result.summary()["tabletop"]["rrtconnect"]
    assert fig["bad_problems"] == 1 and fig["n"] == 1
    bad = next(r for r in result.records if r.problem == "bad-start")
    assert bad.status == "start_invalid" and "world" in bad.detail


def test_cli_bench_planning_and_bad_names(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    proc = run_cli(
        "bench",
        "planning",
        "--families",
        "box",
        "--planners",
        "rrtconnect,rrtc",
        "--problems",
        "1",
        "--budget",
        "1",
        "--json",
        str(out),
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    assert 0.0 <= data["results"]["box"]["rrtconnect"]["success_rate"] <= 1.0
    assert data["paired"]["box"]["rrtconnect vs rrtc"]["problems"] == 1
    assert out.with_suffix(".png").stat().st_size > 5000
    for text in (proc.stdout, out.with_suffix(".md").read_text()):
        assert "problem by problem" in text and "| rrtconnect vs rrtc | S " in text
    proc = run_cli("bench", "planning", "--families", "kitchen")
    assert proc.returncode == 7 and "valid: ['tabletop'" in proc.stderr
    proc = run_cli("bench", "planning", "--planners", "rrt-connect")
    assert proc.returncode == 7 and "rrtconnect" in proc.stderr
    with pytest.raises(PlanningError, match="budget must be > 0"):
        HarnessCfg(budget_s=0)


def test_bench_table_picks_rows_from_a_results_file(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from gaide.cli import main

    results = Path(__file__).resolve().parents[2] / "docs" / "bench" / "ompl_5s.json"
    assert main(["bench", "table", str(results), "--planners", "bitstar,rrtconnect"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert [line.split(" | ")[0] for line in lines[2:]] == ["| bitstar", "| rrtconnect"]
    assert main(["bench", "table", str(results), "--planners", "gaide"]) == 2
    assert "has no runs of ['gaide']" in capsys.readouterr().err
    (tmp_path / "x.json").write_text("[]")
    assert main(["bench", "table", str(tmp_path / "x.json")]) == 2


def test_bench_planning_loads_the_given_weights_folder(tmp_path: Path) -> None:
    weights = tmp_path / "weights"
    weights.mkdir()
    (weights / "mpnet.pt").write_text("not a checkpoint")
    args = ("bench", "planning", "--families", "tabletop", "--problems", "1", "--budget", "1")
    # the folder's file is what the planner loads, not the shipped weights
    proc = run_cli(*args, "--planners", "mpnet", "--weights", str(weights))
    assert proc.returncode == 10 and "mpnet.pt is corrupt" in proc.stderr
    assert sum("error" in line for line in proc.stderr.splitlines()) == 1
    proc = run_cli(*args, "--planners", "rrtconnect,gaide-hybrid", "--weights", str(weights))
    assert proc.returncode == 7 and "has no gaide.pt" in proc.stderr
    # a file named for one model that holds another is refused, not run under a wrong label
    shutil.copy(shipped_checkpoint("gaide"), weights / "mpnet.pt")
    proc = run_cli(*args, "--planners", "mpnet", "--weights", str(weights))
    assert proc.returncode == 10 and "holds a gaide model, not mpnet" in proc.stderr


def test_the_test_split_is_balanced_over_the_categories_and_reported_by_category(
    tmp_path: Path,
) -> None:
    from planning.family_names import CATEGORIES
    from planning.harness import HarnessCfg, run_harness, split_problem
    from planning.harness_report import category_table

    specs = [split_problem("bins", "test", i) for i in range(8)]
    assert [c for _, _, c in specs] == list(CATEGORIES) * 2
    assert split_problem("bins", "test-legacy", 3)[2] is None
    with pytest.raises(PlanningError, match="valid: \\['test', 'test-legacy'"):
        split_problem("bins", "holdout", 0)
    cfg = HarnessCfg(families=("bins",), planners=("rrtc",), problems=4, budget_s=30.0, workers=1)
    result = run_harness(cfg)
    assert sorted(r.difficulty for r in result.records) == sorted(CATEGORIES)
    per = result.summary()["bins"]["rrtc"]["success_by_category"]
    assert set(per) == set(CATEGORIES) and all(v["n"] == 1 for v in per.values())
    table = category_table(result)
    assert all(c in table for c in CATEGORIES) and "| rrtc |" in table


def test_results_do_not_depend_on_the_worker_count() -> None:
    """Each problem's planner seed comes from the problem, not from the worker that runs it:
    one process and two give the same records (the compiled RRT-Connect stops at its first
    solution, far inside the budget, so time does not decide the path)."""

    def records(workers: int) -> list[tuple[str, str, str, float | None]]:
        cfg = HarnessCfg(
            families=("tabletop", "box"),
            planners=("rrtc",),
            problems=3,
            budget_s=60.0,
            workers=workers,
        )
        result = run_harness(cfg)
        return sorted((r.problem, r.planner, r.status, r.cost) for r in result.records)

    one, two = records(1), records(2)
    assert len(one) == 6 and all(status == "success" for _, _, status, _ in one)
    assert one == two


def test_two_planners_are_compared_problem_by_problem_with_exact_p_values() -> None:
    """Made-up records of two planners, A (rrtc) and B (rrtconnect): A solves 10 problems, B
    the same 10 but one and 5 more; of the 9 both solved, A's path is shorter on 7, B's on
    one, and one differs by less than the tie.
    The splits 1 / 5 and 7 / 1 get the exact two-sided sign test's p-values (binomial,
    1/2): 2 * (1 + 6) / 64 and 2 * (1 + 8) / 256."""
    from planning.harness import HarnessResult, RunRecord
    from planning.harness_report import paired_table

    def run(planner: str, i: int, ok: bool, cost: float | None = None) -> RunRecord:
        return RunRecord(
            "bins", f"bins-{i}", i, "free2free", planner, "success" if ok else "failed",
            ok, 0.01, cost if ok else None, 5.0,
        )  # fmt: skip

    a_costs = [1.0] * 6 + [1.0, 1.0, 2.0, 1.0]  # problem 9: only A solves it
    b_costs = [1.5] * 6 + [1.5, 1.0005, 1.0, 0.0]
    records = [run("rrtc", i, True, c) for i, c in enumerate(a_costs)]
    records += [run("rrtconnect", i, i != 9, c) for i, c in enumerate(b_costs)]
    records += [run("rrtc", i, False) for i in range(10, 15)]
    records += [run("rrtconnect", i, True, 3.0) for i in range(10, 15)]
    records += [run("rrtc", 15, False)]  # B never ran problem 15: not paired
    cfg = HarnessCfg(families=("bins",), planners=("rrtc", "rrtconnect"), workers=1)
    result = HarnessResult(cfg, records, {}, 1.0, [])
    d = result.paired()["bins"]["rrtc vs rrtconnect"]
    assert (d["problems"], d["a_only"], d["b_only"]) == (15, 1, 5)
    assert d["success_p"] == pytest.approx(2 * 7 / 64)
    assert (d["both"], d["a_shorter"], d["b_shorter"]) == (9, 7, 1)
    assert d["cost_p"] == pytest.approx(2 * 9 / 256)
    assert "| rrtc vs rrtconnect | S 1 / 5 (p 0.22), C 7 / 1 (p 0.07) |" in paired_table(result)
    assert result.to_json()["paired"]["bins"]["rrtc vs rrtconnect"] == d
