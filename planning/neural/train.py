"""Training: MSE on the normalized step delta_q / step along the oracle paths (both
directions; with several modes, relaxed winner-takes-all:
:func:`~planning.neural.models.step_loss`), AdamW with warm-up and cosine decay, validation on
held-out scenes, checkpoints and resume, CPU or CUDA (mixed precision there), reproducible
from a seed.

Under ``torchrun --nproc_per_node N`` the same code trains data-parallel
(DistributedDataParallel; gloo on CPU, NCCL on GPU): each of the N processes draws
``batch / N`` pairs of the global batch from its own stream, gradients are averaged, and only
rank 0 validates, logs and writes checkpoints.

Each training pair is a waypoint q_i of a path, its next waypoint q_{i+1} and a goal: the
path's end, or (half of the time) a later waypoint of the same path, as the bidirectional
planner asks for steps toward the other tree's end rather than the final goal.
"""

from __future__ import annotations

import logging
import math
import platform
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
import torch
from torch import nn

from gaide_core.errors import ModelError
from planning.neural.checkpoint import (
    Checkpoint,
    file_sha256,
    load_checkpoint,
    robot_signature,
    save_checkpoint,
)
from planning.neural.data import MANIFEST, PathSet, load_paths
from planning.neural.embodiment import RobotCloud, build_embodiment
from planning.neural.models import MODEL_KINDS, ModelCfg, build_model, encode_scene, step_loss
from planning.robot_model import RobotModel

log = logging.getLogger(__name__)


@dataclass
class TrainCfg:
    steps: int = 3000
    batch: int = 128
    lr: float = 1e-3
    weight_decay: float = 1e-4
    warmup: int = 100
    val_share: float = 0.1
    val_every: int = 250
    save_every: int = 500
    seed: int = 0
    device: str = "auto"
    threads: int = 0  # CPU threads for torch; 0: torch's default (all cores)
    # How often a family's training pairs are drawn, relative to the others' (1 for a family
    # not named); validation draws every pair alike. Measured: the shelves at 2 lifted GAIDE
    # and SIMPNet alike (docs/results.md, "Twice the shelves' pairs").
    family_weights: dict[str, float] = field(default_factory=dict)
    # rad: the spread of a Gaussian added to q_t on half the training pairs (the label still
    # points at the oracle's next waypoint), so the network also learns to steer back from
    # the states a rollout drifts into. 0: off. Validation stays on the oracle's own states.
    state_noise: float = 0.0

    def check(self) -> None:
        if self.steps < 1 or self.batch < 1 or not self.lr > 0 or not 0 <= self.val_share < 1:
            raise ModelError(
                "need steps >= 1, batch >= 1, lr > 0 and 0 <= val_share < 1; got "
                f"{self.steps}, {self.batch}, {self.lr}, {self.val_share}"
            )
        if not 0 <= self.state_noise < 1:
            raise ModelError(f"need 0 <= state_noise < 1 rad; got {self.state_noise}")
        bad = {k: w for k, w in self.family_weights.items() if not (0 < w < math.inf)}
        if bad:
            raise ModelError(f"family weights must be finite and > 0; got {bad}")


class Pairs:
    """Training pairs of a set of paths, both directions, drawn in vectorized batches: each
    pair alike, or with ``weights`` (one per family of ``ps``) in proportion to its path's
    family's weight."""

    def __init__(
        self,
        ps: PathSet,
        path_ids: npt.NDArray[np.int64],
        weights: npt.NDArray[np.float64] | None = None,
    ) -> None:
        oriented, scene_of, family_of = [], [], []
        for p in path_ids:
            path = ps.paths[int(p)].astype(np.float32)
            if len(path) < 2:
                continue
            oriented += [path, path[::-1]]
            scene_of += [int(ps.scene_of[p])] * 2
            family_of += [int(ps.families[p])] * 2
        if not oriented:
            raise ModelError("no path with two or more waypoints to train on")
        self.q = np.concatenate(oriented)
        lengths = np.array([len(p) for p in oriented])
        ends = np.cumsum(lengths) - 1  # global index of each oriented path's last waypoint
        owner = np.repeat(np.arange(len(oriented)), lengths)
        not_last = np.ones(len(self.q), bool)
        not_last[ends] = False
        self.index = np.flatnonzero(not_last)  # pairs: waypoint g and g + 1
        self.end = ends[owner][self.index]
        self.scene = np.asarray(scene_of)[owner][self.index]
        self.n_paths = len(oriented) // 2
        self.cdf = None  # drawn alike
        if weights is not None:
            w = np.asarray(weights, float)[np.asarray(family_of)[owner][self.index]]
            self.cdf = np.cumsum(w) / w.sum()

    def __len__(self) -> int:
        return len(self.index)

    def batch(
        self, rng: np.random.Generator, size: int
    ) -> tuple[npt.NDArray[np.int64], np.ndarray, np.ndarray, np.ndarray]:
        """(scene indices, q, goal, q_next) for ``size`` random pairs."""
        if self.cdf is None:
            k = rng.integers(0, len(self.index), size)
        else:
            k = np.minimum(np.searchsorted(self.cdf, rng.random(size)), len(self.index) - 1)
        g, e = self.index[k], self.end[k]
        later = g + 1 + np.floor(rng.random(size) * (e - g)).astype(np.int64)
        goal_idx = np.where(rng.random(size) < 0.5, e, np.minimum(later, e))
        return self.scene[k], self.q[g], self.q[goal_idx], self.q[g + 1]


@dataclass(frozen=True)
class Dist:
    """This process's place in a torchrun job (world 1, rank 0 without one)."""

    world: int = 1
    rank: int = 0
    local_rank: int = 0

    @staticmethod
    def from_env() -> Dist:
        import os

        world = int(os.environ.get("WORLD_SIZE", "1"))
        return Dist(world, int(os.environ.get("RANK", "0")), int(os.environ.get("LOCAL_RANK", "0")))

    @property
    def main(self) -> bool:
        return self.rank == 0


def pick_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name.startswith("cuda") and not torch.cuda.is_available():
        raise ModelError(f"device {name} asked for, but torch sees no CUDA device; use cpu or auto")
    return torch.device(name)


class Trainer:
    def __init__(
        self,
        kind: str,
        robot: RobotModel,
        data: str | Path,
        cfg: TrainCfg,
        model_cfg: ModelCfg | None = None,
        load_progress: Callable[[int, int], None] | None = None,
    ) -> None:
        """``load_progress(done, total)``: the data's shards loaded so far."""
        if kind not in MODEL_KINDS:
            raise ModelError(f"unknown model '{kind}'; valid: {list(MODEL_KINDS)}")
        cfg.check()
        self.kind, self.robot, self.cfg, self.data = kind, robot, cfg, Path(data)
        self.paths = load_paths(data, load_progress)
        self.model_cfg = model_cfg or ModelCfg(step=self.paths.max_step)
        if abs(self.model_cfg.step - self.paths.max_step) > 1e-9:
            raise ModelError(
                f"the model's step {self.model_cfg.step} must equal the data's max_step "
                f"{self.paths.max_step}"
            )
        # Validation holds out whole scenes: a scene's paths share its cloud.
        scenes = np.random.default_rng(cfg.seed).permutation(len(self.paths.scenes))
        held = scenes[: round(cfg.val_share * len(scenes))]
        is_val = np.isin(self.paths.scene_of, held)
        if held.size and is_val.all():
            raise ModelError("too few scenes to hold some out for validation")
        self.train_pairs = Pairs(self.paths, np.flatnonzero(~is_val), self._family_weights())
        self.val_pairs = Pairs(self.paths, np.flatnonzero(is_val)) if is_val.any() else None
        self.embodiment = build_embodiment(robot)
        self.robot_cloud = RobotCloud(robot, self.embodiment)
        self.dist = Dist.from_env()
        if cfg.batch % self.dist.world:
            raise ModelError(
                f"the batch ({cfg.batch}) must divide into the {self.dist.world} processes"
            )
        self.device = pick_device(cfg.device)
        if self.dist.world > 1 and self.device.type == "cuda":
            self.device = torch.device("cuda", self.dist.local_rank)
        if cfg.threads > 0:
            torch.set_num_threads(cfg.threads)
        torch.manual_seed(cfg.seed)
        self.model = build_model(kind, self.model_cfg, self.embodiment, robot.dof).to(self.device)
        self.forward: nn.Module = self.model  # the model, or its DDP wrapper
        if self.dist.world > 1:
            import torch.distributed as td

            if not td.is_initialized():
                td.init_process_group("nccl" if self.device.type == "cuda" else "gloo")
            ids = [self.device.index] if self.device.type == "cuda" else None
            self.forward = nn.parallel.DistributedDataParallel(self.model, device_ids=ids)
        self.opt = torch.optim.AdamW(
            self.model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay
        )
        self.step = 0
        self.history: list[dict[str, float]] = []
        self.wall_s = 0.0
        self.amp = self.device.type == "cuda"
        self.scaler = torch.amp.GradScaler("cuda", enabled=self.amp)

    def _family_weights(self) -> npt.NDArray[np.float64] | None:
        """One weight per family of the data (``cfg.family_weights``), or None: all alike."""
        given = self.cfg.family_weights
        if not given:
            return None
        names = self.paths.family_names
        unknown = sorted(set(given) - set(names))
        if unknown:
            raise ModelError(
                f"family_weights names {unknown}, not in the data; its families: {list(names)}"
            )
        return np.array([given.get(name, 1.0) for name in names])

    def resume(self, path: str | Path) -> None:
        ck = load_checkpoint(path, self.robot, self.kind)
        if ck.cfg != self.model_cfg:
            raise ModelError(
                f"{path} holds a model of other sizes ({ck.cfg.to_dict()}); resume with the "
                "same sizes or train into another file"
            )
        self.model.load_state_dict(ck.state)
        if ck.optimizer is not None:
            self.opt.load_state_dict(ck.optimizer)
        self.step = ck.step
        self.history = list(ck.card.get("history", []))
        self.wall_s = float(ck.card.get("wall_s", 0.0))

    def lr_at(self, step: int) -> float:
        c = self.cfg
        if step < c.warmup:
            return c.lr * (step + 1) / c.warmup
        t = (step - c.warmup) / max(c.steps - c.warmup, 1)
        return c.lr * (0.05 + 0.95 * 0.5 * (1 + math.cos(math.pi * min(t, 1.0))))

    def _tensors(
        self, pairs: Pairs, rng: np.random.Generator, size: int, *, noise: float = 0.0
    ) -> tuple[torch.Tensor, ...]:
        scene_idx, q, goal, q_next = pairs.batch(rng, size)
        if noise > 0:
            moved = rng.random(size) < 0.5
            jitter = rng.normal(0.0, noise, q.shape) * moved[:, None]
            q = np.clip(q + jitter, self.robot.lower, self.robot.upper).astype(np.float32)
        n = self.model_cfg.scene_points
        scenes = self.paths.scenes
        pick = rng.choice(scenes.shape[1], n, replace=False) if scenes.shape[1] > n else slice(None)
        scene = scenes[scene_idx][:, pick]
        robot = self.robot_cloud(q.astype(np.float64)).astype(np.float32)
        dev = self.device
        delta = (q_next - q) / self.model_cfg.step
        return tuple(
            torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32)).to(dev)
            for a in (robot, scene, q, goal, delta)
        )

    def _loss(self, batch: tuple[torch.Tensor, ...], *, train: bool = False) -> torch.Tensor:
        robot, scene, q, goal, delta = batch
        net = self.forward if train else self.model
        with torch.autocast(self.device.type, enabled=self.amp):
            pred = net(robot, encode_scene(self.model, scene), q, goal)
        return step_loss(pred.float(), delta, self.model_cfg.modes)

    def validate(self, batches: int = 8) -> float:
        if self.val_pairs is None:
            return float("nan")
        rng = np.random.default_rng([self.cfg.seed, 1])
        self.model.eval()
        with torch.no_grad():
            losses = [
                float(self._loss(self._tensors(self.val_pairs, rng, self.cfg.batch)))
                for _ in range(batches)
            ]
        self.model.train()
        return float(np.mean(losses))

    def checkpoint(self) -> Checkpoint:
        c = self.cfg
        manifest = self.data / MANIFEST
        card = {
            "model": self.kind,
            "data": str(self.data),
            "data_manifest_sha256": file_sha256(manifest),
            "data_paths": len(self.paths.paths),
            "data_families": list(self.paths.family_names),
            "train_pairs": len(self.train_pairs),
            "val_pairs": len(self.val_pairs) if self.val_pairs else 0,
            "steps": self.step,
            "train": asdict(c),
            "model_cfg": self.model_cfg.to_dict(),
            "parameters": sum(p.numel() for p in self.model.parameters()),
            "processes": self.dist.world,
            "device": str(self.device)
            + (
                f" ({torch.cuda.get_device_name()})"
                if self.device.type == "cuda"
                else f" ({platform.processor() or platform.machine()}, {torch.get_num_threads()} threads)"
            ),
            "torch": str(torch.__version__),
            "wall_s": self.wall_s,
            "history": self.history,
            "final_train_loss": self.history[-1]["train"] if self.history else None,
            "final_val_loss": self.history[-1]["val"] if self.history else None,
        }
        return Checkpoint(
            kind=self.kind,
            cfg=self.model_cfg,
            embodiment=self.embodiment,
            robot=robot_signature(self.robot),
            state={k: v.detach().cpu() for k, v in self.model.state_dict().items()},
            step=self.step,
            optimizer=self.opt.state_dict(),
            card=card,
        )

    def run(
        self, out: str | Path, progress: Callable[[int, dict[str, float]], None] | None = None
    ) -> str:
        """Train to ``cfg.steps``, saving to ``out`` every ``save_every`` steps and at the
        end; returns the final checkpoint's sha256."""
        c = self.cfg
        self.model.train()
        running: list[float] = []
        digest = ""
        t_last = time.perf_counter()
        d = self.dist
        while self.step < c.steps:
            # one stream per process (the single-process stream when there is one)
            rng = np.random.default_rng([c.seed, 0, self.step, *([d.rank] if d.world > 1 else [])])
            torch.manual_seed(c.seed * 1_000_003 + self.step + 7919 * d.rank)
            for g in self.opt.param_groups:
                g["lr"] = self.lr_at(self.step)
            loss = self._loss(
                self._tensors(self.train_pairs, rng, c.batch // d.world, noise=c.state_noise),
                train=True,
            )
            if not torch.isfinite(loss):
                raise ModelError(
                    f"training diverged at step {self.step} (loss {float(loss)}); lower --lr"
                )
            self.opt.zero_grad(set_to_none=True)
            self.scaler.scale(loss).backward()  # DDP averages the gradients over processes
            self.scaler.unscale_(self.opt)
            nn.utils.clip_grad_norm_(self.model.parameters(), 1.0)
            self.scaler.step(self.opt)
            self.scaler.update()
            running.append(self._global_mean(loss))
            self.step += 1
            last = self.step == c.steps
            if self.step % c.val_every == 0 or last:
                now = time.perf_counter()
                self.wall_s += now - t_last
                t_last = now
                entry = {
                    "step": self.step,
                    "train": float(np.mean(running)),
                    "val": self.validate() if d.main else float("nan"),
                }
                running = []
                self.history.append(entry)
                if progress and d.main:
                    progress(self.step, entry)
            if (self.step % c.save_every == 0 or last) and d.main:
                now = time.perf_counter()
                self.wall_s += now - t_last
                t_last = now
                digest = save_checkpoint(out, self.checkpoint())
        if d.world > 1:
            import torch.distributed as td

            td.barrier()
            td.destroy_process_group()
        return digest

    def _global_mean(self, loss: torch.Tensor) -> float:
        """The loss averaged over the processes (the loss of the global batch)."""
        if self.dist.world == 1:
            return float(loss.item())
        import torch.distributed as td

        value = loss.detach().clone()
        td.all_reduce(value)
        return float(value.item()) / self.dist.world
