"""The weights the repository ships: one per model, each loadable for the UR5, small, with a
model card; GAIDE's plan task-family problems whose paths pass the harness's check."""

from __future__ import annotations

import json

import numpy as np
import pytest

from planning.checker import make_checker
from planning.families import generate_problem
from planning.family_names import split_seed
from planning.neural.checkpoint import card_path, file_sha256, load_checkpoint, shipped_checkpoint
from planning.neural.models import MODEL_KINDS
from planning.neural_planner import NeuralPlanner
from planning.path_check import check_path
from planning.planner import PlanStatus
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


@pytest.mark.parametrize("kind", MODEL_KINDS)
def test_every_model_ships_small_weights_with_a_card(kind: str, robot: RobotModel) -> None:
    path = shipped_checkpoint(kind)
    assert path.is_file(), f"the repository ships {path}"
    assert path.stat().st_size <= 20 * 2**20
    ck = load_checkpoint(path, robot, kind)
    card = json.loads(card_path(path).read_text())
    assert card["sha256"] == file_sha256(path)
    assert card["model"] == kind and card["steps"] == ck.step > 0
    assert card["final_val_loss"] is not None and np.isfinite(card["final_val_loss"])


# The retrained weights kept for comparison (issue 13; Tables I and II with ``--weights`` on
# them in docs/results.md): (folder, the data set they name, its path count, model, steps).
RETRAINED = (
    [("weights-train50k", "train50k", 50306, kind, 5000) for kind in MODEL_KINDS]
    + [
        ("weights-train50k-tie", "train50k-tie", 50398, kind, 5000)
        for kind in ("gaide", "mpnet", "simpnet")
    ]
    + [
        ("weights-train50k-clear", "train50k-clear", 50398, kind, 5000)
        for kind in ("gaide", "mpnet", "simpnet")
    ]
    + [
        ("weights-train50k-clear3", "train50k-clear3", 50398, kind, 5000)
        for kind in ("gaide", "mpnet", "simpnet")
    ]
    + [("weights-train50k-clear3-k2", "train50k-clear3", 50398, kind, 5000) for kind in MODEL_KINDS]
    + [("weights-train50k-band-10k", "train50k-band", 50398, kind, 10000) for kind in MODEL_KINDS]
    + [
        ("weights-train50k-band-shelves2", "train50k-band", 50398, kind, 5000)
        for kind in MODEL_KINDS
    ]
    + [
        (f"weights-train50k-band-seed{seed}", "train50k-band", 50398, kind, 5000)
        for seed in (1, 2)
        for kind in ("gaide", "simpnet")
    ]
    + [
        (f"weights-train50k-band-state-noise{seed}", "train50k-band", 50398, kind, 5000)
        for seed in ("", "-seed1", "-seed2")
        for kind in ("gaide", "simpnet")
    ]
    + [("weights-train50k-band-h200", "train50k-band", 50398, kind, 3590) for kind in MODEL_KINDS]
    + [
        ("weights-train50k-band-h200-seed1", "train50k-band", 50398, kind, 3590)
        for kind in ("gaide", "simpnet")
    ]
)


@pytest.mark.parametrize("kind", MODEL_KINDS)
def test_the_shipped_weights_name_the_band_set(kind: str) -> None:
    path = shipped_checkpoint(kind)
    card = json.loads(card_path(path).read_text())
    manifest = path.parent.parent / "train50k-band" / "manifest.json"
    assert card["data_manifest_sha256"] == file_sha256(manifest)
    assert card["data_paths"] == json.loads(manifest.read_text())["paths"] == 50398
    assert card["model_cfg"]["modes"] == 2 and card["steps"] == 5000


@pytest.mark.parametrize(("folder", "data", "paths", "kind", "steps"), RETRAINED)
def test_the_weights_trained_on_the_50k_sets_load_and_name_their_data(
    folder: str, data: str, paths: int, kind: str, steps: int, robot: RobotModel
) -> None:
    path = shipped_checkpoint(kind).parent.parent / folder / f"{kind}.pt"
    ck = load_checkpoint(path, robot, kind)
    card = json.loads(card_path(path).read_text())
    assert card["sha256"] == file_sha256(path) and card["steps"] == ck.step == steps
    manifest = path.parent.parent / data / "manifest.json"
    assert card["data_manifest_sha256"] == file_sha256(manifest)
    assert card["data_paths"] == json.loads(manifest.read_text())["paths"] == paths
    # only the three state-noise folders were trained on jittered states (docs/results.md)
    assert card["train"].get("state_noise", 0.0) == (0.05 if "state-noise" in folder else 0)
    # only the two H200 folders were trained on a GPU, at the paper's batch of 256 (docs/gpu/)
    on_gpu = "h200" in folder
    assert card["device"].startswith("cuda") == on_gpu
    assert (card["train"]["batch"] == 256) == on_gpu


@pytest.mark.parametrize("family", ["tabletop", "shelf_i"])
def test_shipped_gaide_plans_family_problems_that_pass_the_harness_check(
    family: str, robot: RobotModel, spheres: SphereModel
) -> None:
    weights = shipped_checkpoint("gaide")
    for i in range(2):
        p = generate_problem(family, split_seed("test", i), robot, spheres)
        res = NeuralPlanner("gaide-hybrid", weights, mode="hybrid").plan(
            make_checker(robot, spheres, p.world),
            p.start,
            p.goal,
            budget_s=20.0,
            rng=np.random.default_rng(i),
        )
        assert res.status is PlanStatus.SUCCESS, res.detail
        check = check_path(res.path, p.start, p.goal, robot, spheres, p.world)
        assert check.ok, check.detail
