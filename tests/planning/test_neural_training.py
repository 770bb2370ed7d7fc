"""Training data and training: a resumable data set, a tiny model that overfits a handful of
paths, the ``gaide train`` command with its model card and resume."""

from __future__ import annotations

import json
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from gaide_core.errors import ModelError
from planning.neural.data import DataCfg, load_paths, read_manifest
from planning.neural.data_backends import generate
from planning.neural.models import ModelCfg
from planning.neural.train import TrainCfg, Trainer
from planning.oracle import OracleCfg
from planning.robot_model import RobotModel
from tests.conftest import run_cli

TINY = ModelCfg(
    hidden=32, heads=2, ff=64, enc_layers=2, dec_layers=1, scene_points=256, scene_tokens=8
)
# Two scenes (a TableTop and a Box), each with its four categories' start/goal pairs.
DATA = DataCfg(
    families=("tabletop", "box"),
    paths=8,
    shard_size=4,
    oracle=OracleCfg(runs=2, shortcuts=50, band=0),
)


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("data")
    generate(DATA, out, workers=2)
    return out


@pytest.mark.parametrize(
    ("change", "says"),
    [
        ({"families": ("kitchen",)}, "unknown families ['kitchen']"),
        ({"families": ()}, "unknown families []"),
        ({"categories": ("free2free", "free2free")}, "categories must be distinct"),
        ({"categories": ("free2nowhere",)}, "categories must be distinct"),
        ({"paths": 0}, "need paths >= 1 and shard_size >= 1"),
        ({"shard_size": 0}, "need paths >= 1 and shard_size >= 1"),
        ({"max_step": 1.5}, "need 0 < max_step <= 1 rad"),
        ({"scene_points": 16}, "scene_points >= 64"),
        ({"checker": "fcl"}, "unknown checker 'fcl'"),
    ],
)
def test_data_settings_outside_their_limits_are_refused_before_any_work(
    change: dict[str, object], says: str, tmp_path: Path
) -> None:
    with pytest.raises(ModelError, match=re.escape(says)):
        generate(replace(DATA, **change), tmp_path / "never", workers=1)  # type: ignore[arg-type]
    assert not (tmp_path / "never").exists()


def test_the_data_set_holds_resampled_oracle_paths_and_resumes(
    data_dir: Path, robot: RobotModel, tmp_path: Path
) -> None:
    manifest = read_manifest(data_dir)
    assert manifest["complete"] and len(manifest["shards"]) == 2
    assert manifest["paths"] + manifest["failures"] == 8
    seen: list[tuple[int, int]] = []
    ps = load_paths(data_dir, lambda done, total: seen.append((done, total)))
    assert seen == [(0, 2), (1, 2), (2, 2)]  # before each shard, and at the end
    assert len(ps.paths) == manifest["paths"] >= 7
    assert ps.scenes.shape[1:] == (DATA.scene_points, 3)
    # one cloud per scene, shared by its paths; the categories cycle within a scene
    assert len(ps.scenes) == 2 and set(ps.scene_of.tolist()) == {0, 1}
    assert set(ps.categories.tolist()) == {0, 1, 2, 3}
    for p in ps.paths:
        steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
        assert steps.max() <= DATA.max_step + 1e-5
        assert (p >= robot.lower - 1e-6).all() and (p <= robot.upper + 1e-6).all()

    # an interrupted run: one shard lost; the next run remakes it and keeps the other
    copy = tmp_path / "copy"
    copy.mkdir()
    for f in data_dir.iterdir():
        (copy / f.name).write_bytes(f.read_bytes())
    kept = copy / "shard-00000.npz"
    before = kept.stat().st_mtime_ns
    (copy / "shard-00001.npz").unlink()
    again = generate(DATA, copy, workers=1)
    assert again["complete"] and (copy / "shard-00001.npz").is_file()
    assert kept.stat().st_mtime_ns == before
    # the remade shard is byte for byte the one made the first time
    assert (copy / "shard-00001.npz").read_bytes() == (data_dir / "shard-00001.npz").read_bytes()
    with pytest.raises(ModelError, match="other settings"):
        generate(DataCfg(families=("bins",), paths=4, shard_size=2), copy, workers=1)


def test_a_manifest_from_before_the_oracle_tie_share_still_resumes(
    data_dir: Path, tmp_path: Path
) -> None:
    # Data made before OracleCfg.tie, .clearance and .band existed was labelled without
    # them (0).
    for f in data_dir.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    for key in ("tie", "clearance", "clearance_rule", "band", "band_pull"):
        del manifest["settings"]["oracle"][key]
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    (tmp_path / "shard-00001.npz").unlink()
    assert generate(DATA, tmp_path, workers=1)["complete"]
    for other in (
        replace(DATA.oracle, tie=0.05),
        replace(DATA.oracle, band=500),
        replace(DATA.oracle, band=500, band_pull=False),
    ):
        with pytest.raises(ModelError, match="other settings"):
            generate(replace(DATA, oracle=other), tmp_path, workers=1)
    # One made with a clearance but before its per-sphere rule had the tightest sphere's.
    cleared = replace(DATA, oracle=replace(DATA.oracle, clearance=0.02))
    manifest["settings"]["oracle"]["clearance"] = 0.02
    (tmp_path / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(ModelError, match="other settings"):
        generate(cleared, tmp_path, workers=1)
    tightest = replace(cleared, oracle=replace(cleared.oracle, clearance_rule="tightest"))
    (tmp_path / "shard-00001.npz").unlink()
    assert generate(tightest, tmp_path, workers=1)["complete"]


def test_a_ray_cluster_makes_the_same_shards(data_dir: Path, tmp_path: Path) -> None:
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        manifest = generate(DATA, tmp_path, ray="auto")
    finally:
        ray.shutdown()
    assert manifest["complete"]
    for k in range(2):
        name = f"shard-{k:05d}.npz"
        assert (tmp_path / name).read_bytes() == (data_dir / name).read_bytes()


def test_a_corrupt_shard_or_a_missing_manifest_is_named(data_dir: Path, tmp_path: Path) -> None:
    with pytest.raises(ModelError, match=r"no manifest\.json"):
        load_paths(tmp_path)
    for f in data_dir.iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    (tmp_path / "shard-00001.npz").write_bytes(b"not a zip")
    with pytest.raises(ModelError, match=r"shard-00001\.npz: corrupt"):
        load_paths(tmp_path)


def test_a_tiny_model_overfits_a_handful_of_paths(data_dir: Path, robot: RobotModel) -> None:
    cfg = TrainCfg(steps=300, batch=32, lr=3e-3, warmup=20, val_share=0.0, val_every=50, seed=1)
    model_cfg = ModelCfg(**{**TINY.to_dict(), "dropout": 0.0})
    trainer = Trainer("gaide", robot, data_dir, cfg, model_cfg)
    with torch.no_grad():
        first = float(
            trainer._loss(trainer._tensors(trainer.train_pairs, np.random.default_rng(0), 64))
        )
    trainer.run(data_dir / "overfit.pt")
    last = trainer.history[-1]["train"]
    assert last < 0.25 * first, f"loss {first:.4f} -> {last:.4f}"


def test_gaide_train_writes_a_checkpoint_with_its_card_and_resumes(
    data_dir: Path, tmp_path: Path
) -> None:
    out = tmp_path / "m.pt"
    args = ["train", "--model", "mpnet", "--data", str(data_dir), "--out", str(out)]
    sizes = ["--hidden", "16", "--heads", "2", "--ff", "32", "--enc-layers", "2"]
    sizes += ["--scene-points", "128", "--scene-tokens", "4", "--modes", "2"]
    first = run_cli(
        *args, *sizes, "--steps", "6", "--batch", "8", "--device", "cpu", "--threads", "1"
    )
    assert first.returncode == 0, first.stderr
    # stderr is a pipe, as under nohup: plain progress lines, no bar's redraws
    assert "\r" not in first.stderr and "train mpnet: 6/6 steps (100%), train=" in first.stderr
    card = json.loads((tmp_path / "m.pt.card.json").read_text())
    assert card["model"] == "mpnet" and card["steps"] == 6 and card["device"].startswith("cpu")
    assert card["data_paths"] >= 3 and card["history"] and "sha256" in card
    assert card["model_cfg"]["hidden"] == 16 and card["model_cfg"]["scene_tokens"] == 4
    assert card["model_cfg"]["modes"] == 2
    more = run_cli(
        *args, "--steps", "10", "--batch", "8", "--device", "cpu", "--threads", "1", "--resume"
    )
    assert more.returncode == 0, more.stderr
    card = json.loads((tmp_path / "m.pt.card.json").read_text())
    assert card["steps"] == 10 and card["model_cfg"]["hidden"] == 16  # resumed at its sizes
    assert card["model_cfg"]["modes"] == 2

    bad = run_cli("train", "--model", "gaide", "--data", str(tmp_path), "--out", str(out))
    assert bad.returncode == ModelError.exit_code
    assert "not a data directory" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def test_gaide_plan_writes_a_checked_path_or_one_line_with_the_status(
    data_dir: Path, tmp_path: Path
) -> None:
    ckpt = tmp_path / "tiny.pt"
    trained = run_cli(
        *("train", "--model", "gaide", "--data", str(data_dir), "--out", str(ckpt)),
        *("--hidden", "16", "--heads", "2", "--ff", "32", "--enc-layers", "2"),
        *("--steps", "4", "--batch", "8", "--device", "cpu", "--threads", "1"),
    )
    assert trained.returncode == 0, trained.stderr
    out = tmp_path / "path.json"
    # hybrid mode: whatever the barely trained network cannot do, RRT-Connect bridges
    ok = run_cli(
        *("plan", "--family", "box", "--planner", "gaide-hybrid", "--checkpoint", str(ckpt)),
        *("--budget", "30", "-o", str(out)),
    )
    assert ok.returncode == 0, ok.stderr
    plan = json.loads(out.read_text())
    assert plan["status"] == "success" and len(plan["path"]) >= 2
    assert plan["joint_names"][0] == "shoulder_pan_joint" and plan["scene"].startswith("box seed")

    bad_out = tmp_path / "bad.json"
    bad = run_cli(
        *("plan", "--family", "box", "--start", "0,0.3,0,0,0,0", "--planner", "rrtconnect"),
        *("-o", str(bad_out)),
    )
    assert bad.returncode == 7 and "start_invalid" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and not bad_out.exists()

    misuse = run_cli(
        *("plan", "--family", "box", "--planner", "rrtconnect", "--checkpoint", str(ckpt)),
        *("-o", str(bad_out)),
    )
    assert misuse.returncode == 2 and "for the neural planners" in misuse.stderr
    assert not bad_out.exists()
    other = run_cli(
        *("plan", "--family", "box", "--planner", "mpnet", "--checkpoint", str(ckpt)),
        *("-o", str(bad_out)),
    )
    assert other.returncode == ModelError.exit_code and "holds a gaide model, not mpnet" in (
        other.stderr
    )
    assert not bad_out.exists()


def test_torchrun_with_two_processes_follows_the_single_process_loss_curve(
    data_dir: Path, tmp_path: Path
) -> None:
    # The same global batch split over two gloo processes: the same optimisation, other
    # random pairs, so the loss curves agree within the noise of the batches.
    import json
    import shutil
    import subprocess
    import sys

    args = [
        *("train", "--model", "mpnet", "--data", str(data_dir), "--hidden", "32"),
        *("--ff", "64", "--steps", "150", "--batch", "32", "--lr", "3e-3", "--val-every", "25"),
        *("--device", "cpu", "--threads", "1"),
    ]
    one = run_cli(*args, "--out", str(tmp_path / "one.pt"))
    assert one.returncode == 0, one.stderr
    torchrun = shutil.which("torchrun", path=str(Path(sys.executable).parent))
    assert torchrun is not None, "torchrun comes with torch"
    two = subprocess.run(
        [torchrun, "--nproc_per_node", "2", "--no-python", sys.executable, "-m", "gaide", *args,
         "--out", str(tmp_path / "two.pt")],
        capture_output=True, text=True, timeout=600, env={**os.environ, "OMP_NUM_THREADS": "1"},
    )  # fmt: skip
    assert two.returncode == 0, two.stderr[-2000:]
    curves = [json.loads((tmp_path / f"{n}.pt.card.json").read_text()) for n in ("one", "two")]
    assert [c["processes"] for c in curves] == [1, 2]
    a, b = (np.array([h["train"] for h in c["history"]]) for c in curves)
    assert len(a) == len(b) == 6
    assert a[-1] < 0.7 * a[0] and b[-1] < 0.7 * b[0], ("both learn", a, b)
    assert np.all(np.abs(a - b) <= 0.25 * np.maximum(a, b)), (a, b)


def test_family_weights_draw_a_familys_pairs_that_much_more_often(
    data_dir: Path, robot: RobotModel, tmp_path: Path
) -> None:
    from planning.neural.train import Pairs

    ps = load_paths(data_dir)
    ids = np.arange(len(ps.paths))
    box = ps.family_names.index("box")

    def box_share(pairs: Pairs) -> float:
        scenes = pairs.batch(np.random.default_rng(0), 40_000)[0]
        family_of_scene = {int(s): int(f) for s, f in zip(ps.scene_of, ps.families, strict=True)}
        return float(np.mean([family_of_scene[int(s)] == box for s in scenes]))

    alike = Pairs(ps, ids)
    weights = np.ones(len(ps.family_names))
    weights[box] = 3.0
    tripled = Pairs(ps, ids, weights)
    share = box_share(alike)  # the box's share of the pairs
    expected = 3 * share / (3 * share + (1 - share))
    assert 0.1 < share < 0.9
    assert abs(box_share(tripled) - expected) < 0.01, (box_share(tripled), expected)

    cfg = TrainCfg(steps=2, batch=8, val_share=0.0, family_weights={"box": 2.0})
    trainer = Trainer("mpnet", robot, data_dir, cfg, TINY)
    trainer.run(tmp_path / "w.pt")
    card = json.loads((tmp_path / "w.pt.card.json").read_text())
    assert card["train"]["family_weights"] == {"box": 2.0}
    with pytest.raises(ModelError, match=r"names \['shelf_ix'\], not in the data"):
        Trainer("mpnet", robot, data_dir, replace(cfg, family_weights={"shelf_ix": 2.0}), TINY)
    with pytest.raises(ModelError, match="finite and > 0"):
        Trainer("mpnet", robot, data_dir, replace(cfg, family_weights={"box": 0.0}), TINY)
    bad = run_cli(
        "train", "--model", "mpnet", "--data", str(data_dir), "--out", str(tmp_path / "x.pt"),
        "--family-weights", "box=two",
    )  # fmt: skip
    assert bad.returncode != 0 and "not FAMILY=W" in bad.stderr
    assert not (tmp_path / "x.pt").exists()


def test_state_noise_moves_half_the_states_and_keeps_the_oracles_next_waypoint(
    data_dir: Path, robot: RobotModel, tmp_path: Path
) -> None:
    cfg = TrainCfg(steps=2, batch=8, val_share=0.0, state_noise=0.05)
    trainer = Trainer("mpnet", robot, data_dir, cfg, TINY)
    size = 4000
    _, q, _, q_next = trainer.train_pairs.batch(np.random.default_rng(3), size)
    tensors = trainer._tensors(trainer.train_pairs, np.random.default_rng(3), size, noise=0.05)
    q_in, delta = tensors[2].numpy(), tensors[4].numpy()
    moved = np.any(np.abs(q_in - q) > 1e-6, axis=1)
    assert abs(moved.mean() - 0.5) < 0.03, moved.mean()
    inside = (q_in >= robot.lower - 1e-6) & (q_in <= robot.upper + 1e-6)
    assert inside.all()
    free = np.all((q[moved] > robot.lower + 0.3) & (q[moved] < robot.upper - 0.3), axis=1)
    assert abs(float(np.std(q_in[moved][free] - q[moved][free])) - 0.05) < 0.005
    # the label is the step from the state the network sees to the oracle's next waypoint
    np.testing.assert_allclose(delta * trainer.model_cfg.step, q_next - q_in, atol=1e-5)
    clean = trainer._tensors(trainer.train_pairs, np.random.default_rng(3), size)
    np.testing.assert_array_equal(clean[2].numpy(), q)

    trainer.run(tmp_path / "w.pt")
    card = json.loads((tmp_path / "w.pt.card.json").read_text())
    assert card["train"]["state_noise"] == 0.05
    with pytest.raises(ModelError, match="state_noise"):
        Trainer("mpnet", robot, data_dir, replace(cfg, state_noise=-0.1), TINY)
