"""The neural samplers: the graph mask, shapes and gradients, dropout as the randomness,
checkpoints."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from gaide_core.errors import ModelError
from planning.neural.checkpoint import Checkpoint, load_checkpoint, robot_signature, save_checkpoint
from planning.neural.embodiment import Embodiment, RobotCloud, build_embodiment
from planning.neural.models import (
    MODEL_KINDS,
    WTA_RELAX,
    Gaide,
    ModelCfg,
    build_model,
    graph_mask,
    step_loss,
)
from planning.neural.sampler import NeuralSampler
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel

TINY = ModelCfg(
    hidden=32, heads=2, ff=64, enc_layers=2, dec_layers=1, scene_points=256, scene_tokens=8
)


@pytest.fixture(scope="module")
def embodiment(robot: RobotModel) -> Embodiment:
    return build_embodiment(robot)


def _inputs(
    robot: RobotModel, embodiment: Embodiment, batch: int, seed: int = 0
) -> tuple[torch.Tensor, ...]:
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.lower, robot.upper, (batch, robot.dof))
    goal = rng.uniform(robot.lower, robot.upper, (batch, robot.dof))
    cloud = RobotCloud(robot, embodiment)(q)
    scene = rng.uniform(-0.8, 0.8, (1, TINY.scene_points, 3))
    return tuple(torch.from_numpy(a.astype(np.float32)) for a in (cloud, scene, q, goal))


def test_the_mask_is_the_embodiment_graph(embodiment: Embodiment) -> None:
    kr, kw = embodiment.n_tokens, TINY.scene_tokens
    blocked = graph_mask(embodiment, kw).numpy()
    allowed = ~blocked
    assert allowed.shape == (kr + kw, kr + kw)
    assert allowed.diagonal().all(), "every token attends to itself"
    assert allowed[:kr, kr:].all(), "every robot token receives from every scene token"
    assert not allowed[kr:, :kr].any(), "scene tokens receive from no robot token"
    assert (allowed[kr:, kr:] == np.eye(kw, dtype=bool)).all(), "scene tokens see only themselves"
    links = embodiment.token_link
    for i in range(kr):
        for j in range(kr):
            same_or_adjacent = embodiment.adjacency[links[i], links[j]]
            assert allowed[i, j] == same_or_adjacent
    assert (allowed[:kr, :kr] == allowed[:kr, :kr].T).all(), "the robot graph is undirected"
    # the UR5's chain is long enough that some token pairs are not linked
    assert not allowed[:kr, :kr].all()


def _layer_output(
    layer: torch.nn.Module, x: torch.Tensor, mask: torch.Tensor | None
) -> torch.Tensor:
    layer.eval()
    with torch.no_grad():
        return layer(x, src_mask=mask)


def test_a_masked_layer_only_passes_information_along_the_graph(
    robot: RobotModel, embodiment: Embodiment
) -> None:
    model = Gaide(TINY, embodiment, robot.dof, "interleaved")
    kr, kw = embodiment.n_tokens, TINY.scene_tokens
    masked, unmasked = model.encoder[0], model.encoder[1]
    assert model.layer_masked(0) and not model.layer_masked(1)
    gen = torch.Generator().manual_seed(0)
    x = torch.randn(1, kr + kw, TINY.hidden, generator=gen)
    # a random change (a constant shift would vanish in the layer's LayerNorm)
    kick = 3.0 * torch.randn(TINY.hidden, generator=gen)

    # a scene token's output does not change when another scene token's input changes
    y = x.clone()
    y[0, kr + 1] += kick
    a = _layer_output(masked, x, model.mask)
    b = _layer_output(masked, y, model.mask)
    assert torch.allclose(a[0, kr], b[0, kr], atol=1e-6)
    assert not torch.allclose(a[0, 0], b[0, 0], atol=1e-4), "robot tokens hear every scene token"
    # ... while an unmasked layer mixes them
    a, b = _layer_output(unmasked, x, None), _layer_output(unmasked, y, None)
    assert not torch.allclose(a[0, kr], b[0, kr], atol=1e-4)

    # a robot token's output does not change when a non-adjacent link's token changes
    graph = embodiment.token_graph()
    i, j = next((i, j) for i in range(kr) for j in range(kr) if not graph[i, j])
    k = next(k for k in range(kr) if graph[i, k] and k != i)
    for changed, should_change in ((j, False), (k, True)):
        y = x.clone()
        y[0, changed] += kick
        a = _layer_output(masked, x, model.mask)
        b = _layer_output(masked, y, model.mask)
        assert torch.allclose(a[0, i], b[0, i], atol=1e-6) != should_change


@pytest.mark.parametrize("modes", [1, 3])
@pytest.mark.parametrize("kind", MODEL_KINDS)
def test_every_model_maps_inputs_to_a_step_and_every_weight_learns(
    kind: str, modes: int, robot: RobotModel, embodiment: Embodiment
) -> None:
    torch.manual_seed(0)
    model = build_model(kind, ModelCfg(**{**TINY.to_dict(), "modes": modes}), embodiment, robot.dof)
    cloud, scene, q, goal = _inputs(robot, embodiment, 5)
    tokens = model.backbone.encode_scene(scene)
    assert tokens.shape == (1, TINY.scene_tokens, TINY.hidden)
    out = model(cloud, tokens, q, goal)
    assert out.shape == (5, modes * robot.dof) and torch.isfinite(out).all()
    out.pow(2).sum().backward()
    dead = [n for n, p in model.named_parameters() if p.grad is None or not p.grad.abs().sum() > 0]
    assert not dead, f"parameters without gradient: {dead}"


def test_ablations_differ_only_in_where_the_mask_applies(
    robot: RobotModel, embodiment: Embodiment
) -> None:
    layers = ModelCfg(**{**TINY.to_dict(), "enc_layers": 4})
    pattern = {
        kind: [build_model(kind, layers, embodiment, robot.dof).layer_masked(i) for i in range(4)]  # type: ignore[operator]
        for kind in ("gaide", "gaide-v", "gaide-h")
    }
    assert pattern == {
        "gaide": [True, False, True, False],
        "gaide-v": [False] * 4,
        "gaide-h": [True] * 4,
    }


def _checkpoint(
    kind: str, robot: RobotModel, embodiment: Embodiment, tmp_path: Path, seed: int = 0
) -> Path:
    torch.manual_seed(seed)
    model = build_model(kind, TINY, embodiment, robot.dof)
    path = tmp_path / f"{kind}.pt"
    save_checkpoint(
        path,
        Checkpoint(
            kind=kind,
            cfg=TINY,
            embodiment=embodiment,
            robot=robot_signature(robot),
            state=model.state_dict(),
            card={"note": "test"},
        ),
    )
    return path


def test_dropout_draws_different_samples_and_a_seed_repeats_them(
    robot: RobotModel, embodiment: Embodiment, tmp_path: Path
) -> None:
    sampler = NeuralSampler(_checkpoint("gaide", robot, embodiment, tmp_path), robot)
    rng = np.random.default_rng(3)
    scene = sampler.scene(rng.uniform(-0.8, 0.8, (500, 3)))
    q, goal = robot.named_configuration("home"), np.zeros(robot.dof)
    torch.manual_seed(7)
    a = sampler.sample(scene, q, goal, 4)
    torch.manual_seed(7)
    b = sampler.sample(scene, q, goal, 4)
    assert np.array_equal(a, b), "same seed, same samples"
    assert np.ptp(a, axis=0).max() > 1e-4, "rollouts of one batch differ (dropout is on)"
    assert np.linalg.norm(a - q, axis=1).max() <= sampler.step + 1e-9


def test_the_step_loss_trains_the_nearest_of_several_hypotheses() -> None:
    delta = torch.tensor([[1.0, 0.0], [0.0, 1.0]])
    one = torch.tensor([[0.5, 0.0], [0.0, 0.0]])
    assert torch.isclose(step_loss(one, delta, 1), torch.nn.functional.mse_loss(one, delta))
    # two hypotheses per pair: pair 0's second is exact, pair 1's first is 0.5 off in one joint
    two = torch.tensor([[3.0, 0.0, 1.0, 0.0], [0.0, 0.5, 0.0, -1.0]], requires_grad=True)
    err = torch.tensor([[2.0, 0.0], [0.125, 2.0]])  # per pair and hypothesis, mean over joints
    expected = ((1 - WTA_RELAX) * err.min(1).values + WTA_RELAX * err.mean(1)).mean()
    loss = step_loss(two, delta, 2)
    assert torch.isclose(loss, expected)
    loss.backward()
    assert two.grad is not None
    # pair 1, joint 1: the winner (0.5 off) takes the pull, the loser (2 off) only the
    # relaxation's share; d err / d x = (x - target) for a mean over 2 joints, 1/2 for the batch
    r = WTA_RELAX
    assert torch.isclose(two.grad[1, 1], torch.tensor((1 - r + r / 2) * -0.5 / 2))
    assert torch.isclose(two.grad[1, 3], torch.tensor(r / 2 * -2.0 / 2))


def test_each_mode_gets_every_kth_rollout(
    robot: RobotModel, embodiment: Embodiment, tmp_path: Path
) -> None:
    cfg = ModelCfg(**{**TINY.to_dict(), "modes": 2, "dropout": 0.0})
    torch.manual_seed(0)
    model = build_model("gaide", cfg, embodiment, robot.dof)
    path = tmp_path / "gaide2.pt"
    save_checkpoint(
        path,
        Checkpoint(
            kind="gaide", cfg=cfg, embodiment=embodiment, robot=robot_signature(robot),
            state=model.state_dict(), card={},
        ),
    )  # fmt: skip
    sampler = NeuralSampler(path, robot)
    scene = sampler.scene(np.random.default_rng(3).uniform(-0.8, 0.8, (500, 3)))
    q, goal = robot.named_configuration("home"), np.zeros(robot.dof)
    a = sampler.sample(scene, q, goal, 6)
    # no dropout: the rollouts are the two modes' steps, taken in turn
    assert np.allclose(a[0::2], a[0]) and np.allclose(a[1::2], a[1])
    assert np.linalg.norm(a[0] - a[1]) > 1e-4


def test_a_checkpoint_round_trips_and_refuses_what_it_is_not(
    robot: RobotModel, embodiment: Embodiment, tmp_path: Path
) -> None:
    path = _checkpoint("simpnet", robot, embodiment, tmp_path)
    assert (tmp_path / "simpnet.pt.card.json").is_file()
    ck = load_checkpoint(path, robot, "simpnet")
    torch.manual_seed(0)
    original = build_model("simpnet", TINY, embodiment, robot.dof).eval()
    loaded = ck.model().eval()
    cloud, scene, q, goal = _inputs(robot, embodiment, 3)
    with torch.no_grad():
        tokens = original.backbone.encode_scene(scene)
        assert torch.equal(original(cloud, tokens, q, goal), loaded(cloud, tokens, q, goal))

    with pytest.raises(ModelError, match="holds a simpnet model, not gaide"):
        load_checkpoint(path, robot, "gaide")
    with pytest.raises(ModelError, match="does not exist"):
        load_checkpoint(tmp_path / "missing.pt", robot)
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(path.read_bytes()[:1000])
    with pytest.raises(ModelError, match="corrupt"):
        load_checkpoint(corrupt, robot)
    other = torch.load(path, weights_only=True)
    other["robot"] = dict(other["robot"], joints=["a", "b", "c", "d", "e", "f", "g"], dof=7)
    torch.save(other, tmp_path / "other.pt")
    with pytest.raises(ModelError, match="trained for another robot"):
        load_checkpoint(tmp_path / "other.pt", robot)


def test_a_scene_cloud_outside_the_workspace_is_refused(
    robot: RobotModel, embodiment: Embodiment, tmp_path: Path
) -> None:
    from gaide_core.errors import PerceptionError

    sampler = NeuralSampler(_checkpoint("mpnet", robot, embodiment, tmp_path), robot)
    with pytest.raises(PerceptionError, match="non-empty"):
        sampler.scene(np.zeros((0, 3)))
    with pytest.raises(PerceptionError, match="base frame"):
        sampler.scene(np.full((100, 3), 40.0))


@pytest.mark.parametrize(
    "sizes",
    [
        {"hidden": 30, "heads": 4},
        {"enc_layers": 0},
        {"scene_points": 8},
        {"dropout": 1.0},
        {"modes": 0},
    ],
)
def test_model_sizes_out_of_range_are_refused(sizes: dict[str, float]) -> None:
    with pytest.raises(ModelError, match=r"model sizes|dropouts"):
        ModelCfg(**sizes)  # type: ignore[arg-type]


def test_the_shipped_weights_refuse_a_ur10_for_its_link_lengths(
    robot: RobotModel, tmp_path: Path
) -> None:
    """Same joint names as the UR5, other link lengths: the weights say what differs."""
    from planning.neural.checkpoint import shipped_checkpoint
    from planning.robot_model import load_robot

    ur5 = (Path(__file__).parents[2] / "planning" / "data" / "ur5.yaml").read_text()
    config = tmp_path / "ur10.yaml"
    config.write_text(
        "\n".join(
            line.replace("ur5_robot.urdf", "ur10_robot.urdf")
            for line in ur5.splitlines()
            if not line.startswith(("srdf:", "spheres:"))
        )
    )
    ur10 = load_robot(config)
    assert ur10.joint_names == robot.joint_names
    load_checkpoint(shipped_checkpoint("gaide"), robot, "gaide")  # the UR5 passes
    with pytest.raises(
        ModelError,
        match=r"joint shoulder_pan_joint sits 0.0892 m .* 0.1273 m here \(link lengths differ\)",
    ):
        load_checkpoint(shipped_checkpoint("gaide"), ur10, "gaide")


def test_weights_for_other_spheres_of_the_same_robot_load_with_a_warning(
    robot: RobotModel,
    embodiment: Embodiment,
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
) -> None:
    path = _checkpoint("gaide", robot, embodiment, tmp_path)
    assert robot_signature(robot)["spheres"] is not None
    load_checkpoint(path, robot, "gaide")
    assert "sphere model" not in caplog.text
    assert robot.config.spheres is not None
    spheres = SphereModel.load_for(robot.config.spheres, robot)
    grown = SphereModel(spheres.links, spheres.centers, spheres.radii + 0.01)
    grown.save(tmp_path / "grown.yaml")
    other = RobotModel(robot.config.replace(spheres=tmp_path / "grown.yaml"))
    load_checkpoint(path, other, "gaide")
    assert "trained with another sphere model of this robot" in caplog.text
