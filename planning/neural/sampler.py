"""The sampler the neural planner draws from: a trained model behind one protocol, with the
scene encoded once per problem and a batch of stochastic rollouts (dropout kept on) per
forward pass."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch

from gaide_core.errors import ModelError, PerceptionError
from gaide_core.types import Array
from planning.neural.checkpoint import load_checkpoint
from planning.neural.embodiment import RobotCloud
from planning.neural.models import encode_scene, hypotheses
from planning.robot_model import RobotModel

# The scene cloud must lie around the robot, in the base frame: points further than this
# from the base (m) are not of the workspace.
WORKSPACE_RADIUS_M = 2.5


class Sampler(Protocol):
    """Proposes next configurations toward a goal in an encoded scene."""

    name: str

    def scene(self, cloud: Array) -> Any:
        """The scene (N, 3) base-frame points, encoded for :meth:`sample`."""
        ...

    def sample(self, scene: Any, q: Array, goal: Array, n: int) -> Array:
        """``n`` proposals (n, dof) for the configuration after ``q`` toward ``goal``."""
        ...


class NeuralSampler:
    """A checkpoint's model as a :class:`Sampler`. Proposals are ``q + delta`` with the step
    clipped to the data's maximum step; a model of K modes gives each mode every K-th
    rollout."""

    def __init__(
        self,
        checkpoint: str | Path,
        robot: RobotModel,
        kind: str | None = None,
        device: str = "cpu",
    ) -> None:
        ck = load_checkpoint(checkpoint, robot, kind)
        self.name = ck.kind
        self.checkpoint = Path(checkpoint)
        self.cfg = ck.cfg
        self.device = torch.device(device)
        self.model = ck.model().to(self.device)
        self.model.train()  # dropout on: the sampler's randomness (no batch norm anywhere)
        self.robot_cloud = RobotCloud(robot, ck.embodiment)
        # MPNet has no robot-cloud encoder: its clouds need not be computed
        self.reads_robot_cloud = getattr(self.model.backbone, "robot_sa", None) is not None
        self.step = float(ck.cfg.step)

    def scene(self, cloud: Array) -> torch.Tensor:
        pts = np.asarray(cloud, np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
            raise PerceptionError(
                f"the scene cloud must be a non-empty (N, 3) array in the base frame; got shape {pts.shape}"
            )
        finite = np.isfinite(pts).all(axis=1)
        near = np.linalg.norm(pts, axis=1) < WORKSPACE_RADIUS_M
        pts = pts[finite & near]
        if len(pts) < 16:
            raise PerceptionError(
                f"the scene cloud has {len(pts)} finite points within {WORKSPACE_RADIUS_M} m of "
                "the robot base; it must be in the base frame and hold at least 16"
            )
        n = self.cfg.scene_points
        # A fixed subset (by index) keeps the encoding deterministic for a given cloud.
        idx = (
            np.linspace(0, len(pts) - 1, n).round().astype(np.int64)
            if len(pts) > n
            else slice(None)
        )
        t = torch.from_numpy(pts[idx].astype(np.float32))[None].to(self.device)
        with torch.no_grad():
            return encode_scene(self.model, t)

    def sample(self, scene: torch.Tensor, q: Array, goal: Array, n: int) -> Array:
        Q = np.repeat(np.asarray(q, np.float64)[None], n, axis=0)
        cloud = self.robot_cloud(Q) if self.reads_robot_cloud else np.zeros((n, 0, 3))
        robot = torch.from_numpy(cloud.astype(np.float32)).to(self.device)
        qt = torch.from_numpy(Q.astype(np.float32)).to(self.device)
        gt = torch.from_numpy(np.repeat(np.asarray(goal, np.float32)[None], n, axis=0)).to(
            self.device
        )
        with torch.no_grad():
            pred = hypotheses(self.model(robot, scene, qt, gt), self.cfg.modes)
        # rollout i takes mode i mod K: the modes share the rollouts evenly
        delta = pred[torch.arange(n), torch.arange(n) % self.cfg.modes].double().cpu().numpy()
        delta *= self.step
        norm = np.linalg.norm(delta, axis=1, keepdims=True)
        delta *= np.minimum(1.0, self.step / np.maximum(norm, 1e-12))
        return Q + delta


_CACHE: dict[tuple[str, str, int], NeuralSampler] = {}


def cached_sampler(
    checkpoint: str | Path, robot: RobotModel, kind: str | None = None
) -> NeuralSampler:
    """One sampler per checkpoint, robot and process (loading costs ~50 ms)."""
    key = (str(Path(checkpoint).resolve()), kind or "", id(robot))
    if key not in _CACHE:
        if not Path(checkpoint).is_file():
            raise ModelError(
                f"checkpoint {checkpoint} does not exist (train one with `gaide train`)"
            )
        _CACHE[key] = NeuralSampler(checkpoint, robot, kind)
    return _CACHE[key]
