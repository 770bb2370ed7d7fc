"""GAIDE (graph-masked transformer encoder, one-query decoder), its ablations GAIDE-V (never
masked) and GAIDE-H (always masked), and the baselines MPNet and SIMPNet with the same scene
embedding.

Every model maps (robot cloud at q_t, scene tokens, q_t, q_goal) to a normalized step
delta_q / ``cfg.step``, or with ``cfg.modes`` = K > 1 to K such steps (``(B, K * dof)``, see
:func:`hypotheses`); dropout stays active when sampling (it is the sampler's randomness).
Joint values enter scaled by 1/pi.

Attention-mask convention (torch's): ``mask[i, j]`` is True where query token i may NOT attend
to key token j; information flows from key j to query i. Token order: the K_r robot tokens,
then the K_w scene tokens. A masked layer lets robot token i attend to robot token j when
their links are the same or adjacent, every robot token attend to every scene token (the
directed scene -> robot edges) and every token attend to itself; a scene token sees only
itself.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from gaide_core.errors import ModelError
from planning.neural.embodiment import Embodiment
from planning.neural.pointnet import SetAbstraction

MODEL_KINDS = ("gaide", "gaide-v", "gaide-h", "mpnet", "simpnet")


@dataclass
class ModelCfg:
    """Sizes, chosen by measured speed and quality on a 2-core CPU (see docs/results.md)."""

    hidden: int = 64
    heads: int = 4
    ff: int = 128
    enc_layers: int = 4
    dec_layers: int = 1
    dropout: float = 0.1
    mlp_dropout: float = 0.5  # MPNet's
    scene_points: int = 1024
    scene_tokens: int = 16
    scene_radius: float = 0.3
    scene_nsample: int = 32
    robot_radius: float = 0.12
    robot_nsample: int = 16
    step: float = 0.3  # rad: the data's maximum joint step, and the output's scale
    # MLP_I reads a role flag beside the joints (0: q_t, 1: q_goal). The paper's sum
    # z_t + z_goal of one shared MLP is symmetric in q_t and q_goal, so the network must tell
    # them apart from the robot cloud alone; with the flag it need not (measured on the
    # shipped data: GAIDE's validation loss 0.065 -> 0.032 at the same 3,000 steps).
    joint_roles: bool = True
    # Steps the head proposes at once. One step regresses toward the mean of the labels, which
    # on a shelf can lie on the board between two routes of equal cost; K heads trained by
    # relaxed winner-takes-all (:func:`step_loss`) can each keep one route.
    modes: int = 1
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        counts = {
            "hidden": self.hidden, "heads": self.heads, "ff": self.ff,
            "enc_layers": self.enc_layers, "dec_layers": self.dec_layers,
            "scene_tokens": self.scene_tokens, "scene_nsample": self.scene_nsample,
            "robot_nsample": self.robot_nsample, "modes": self.modes,
        }  # fmt: skip
        wrong = [f"{k} = {v} (must be >= 1)" for k, v in counts.items() if v < 1]
        if not wrong and self.hidden % self.heads:
            wrong.append(f"hidden = {self.hidden} (must be a multiple of heads = {self.heads})")
        if self.scene_points < self.scene_tokens:
            wrong.append(
                f"scene_points = {self.scene_points} (must be >= scene_tokens = "
                f"{self.scene_tokens})"
            )
        if wrong:
            raise ModelError("model sizes out of range: " + "; ".join(wrong))
        if not (0 <= self.dropout < 1 and 0 <= self.mlp_dropout < 1) or not self.step > 0:
            raise ModelError(
                f"need dropouts in [0, 1) and step > 0; got {self.dropout}, "
                f"{self.mlp_dropout}, {self.step}"
            )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


# The share of the mean over all K hypotheses in :func:`step_loss` (relaxed winner-takes-all,
# Rupprecht et al., ICCV 2017): with none, a hypothesis that never wins is never trained.
WTA_RELAX = 0.05


def hypotheses(pred: Tensor, modes: int) -> Tensor:
    """A model's output (B, K * dof) as its K steps (B, K, dof)."""
    return pred.reshape(len(pred), modes, -1)


def step_loss(pred: Tensor, delta: Tensor, modes: int) -> Tensor:
    """MSE of the step for one mode; for K modes, per pair the smallest of the K hypotheses'
    errors, plus ``WTA_RELAX`` of their mean."""
    if modes == 1:
        return nn.functional.mse_loss(pred, delta)
    err = ((hypotheses(pred, modes) - delta[:, None]) ** 2).mean(dim=-1)  # (B, K)
    return ((1 - WTA_RELAX) * err.min(dim=1).values + WTA_RELAX * err.mean(dim=1)).mean()


def _mlp(widths: list[int], dropout: float = 0.0) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(widths[:-1]):
        layers += [nn.Linear(a, b), nn.ReLU()]
        if dropout:
            layers.append(nn.Dropout(dropout))
    layers.append(nn.Linear(widths[-2], widths[-1]))
    return nn.Sequential(*layers)


def sinusoidal(n: int, dim: int) -> Tensor:
    """(n, dim) sinusoidal positional encoding (Vaswani et al.)."""
    pos = torch.arange(n, dtype=torch.float32)[:, None]
    freq = torch.exp(torch.arange(0, dim, 2, dtype=torch.float32) * (-math.log(10000.0) / dim))
    pe = torch.zeros(n, dim)
    pe[:, 0::2] = torch.sin(pos * freq)
    pe[:, 1::2] = torch.cos(pos * freq[: dim // 2])
    return pe


def graph_mask(embodiment: Embodiment, scene_tokens: int) -> Tensor:
    """(T, T) bool attention mask of a masked layer (True: blocked), T = K_r + K_w."""
    kr = embodiment.n_tokens
    T = kr + scene_tokens
    allowed = np.zeros((T, T), bool)
    allowed[:kr, :kr] = embodiment.token_graph()
    allowed[:kr, kr:] = True  # scene -> robot
    allowed[np.arange(T), np.arange(T)] = True  # self-loops
    return torch.from_numpy(~allowed)


class _Backbone(nn.Module):
    """What every model shares: the scene and robot set abstractions and MLP_I."""

    def __init__(
        self, cfg: ModelCfg, embodiment: Embodiment, dof: int, robot_cloud: bool = True
    ) -> None:
        super().__init__()
        h = cfg.hidden
        self.cfg, self.dof = cfg, dof
        self.scene_sa = SetAbstraction(
            cfg.scene_tokens, cfg.scene_radius, cfg.scene_nsample, (32, 64, h)
        )
        # MPNet sees the robot only through q: it has no robot-cloud encoder.
        self.robot_sa = (
            SetAbstraction(embodiment.n_tokens, cfg.robot_radius, cfg.robot_nsample, (32, 64, h))
            if robot_cloud
            else None
        )
        self.register_buffer("token_idx", torch.from_numpy(embodiment.token_idx.copy()))
        self.roles = cfg.joint_roles and robot_cloud  # MPNet concatenates: no symmetry
        self.mlp_i = _mlp([dof + int(self.roles), h, h])

    def encode_scene(self, scene: Tensor) -> Tensor:
        """Scene tokens (B, K_w, H) of clouds (B, N, 3), base frame (m)."""
        tokens, _ = self.scene_sa(scene)
        return tokens

    def robot_tokens(self, robot: Tensor) -> Tensor:
        if self.robot_sa is None:
            raise ValueError("this model has no robot-cloud encoder")
        tokens, _ = self.robot_sa(robot, self.token_idx)
        return tokens

    def joints(self, q: Tensor, goal: bool = False) -> Tensor:
        """MLP_I of joint vectors (B, dof) rad; ``goal`` sets the role flag."""
        x = q / math.pi
        if self.roles:
            x = torch.cat([x, torch.full_like(x[:, :1], float(goal))], dim=1)
        return self.mlp_i(x)


class Gaide(nn.Module):
    """GAIDE; ``masking`` 'interleaved' (the paper: masked, unmasked, ..., first masked),
    'none' (GAIDE-V) or 'all' (GAIDE-H)."""

    pe: Tensor
    mask: Tensor

    def __init__(
        self, cfg: ModelCfg, embodiment: Embodiment, dof: int, masking: str = "interleaved"
    ) -> None:
        super().__init__()
        if masking not in ("interleaved", "none", "all"):
            raise ValueError(f"masking must be interleaved, none or all; got {masking!r}")
        h = cfg.hidden
        self.backbone = _Backbone(cfg, embodiment, dof)
        self.masking = masking
        T = embodiment.n_tokens + cfg.scene_tokens
        self.register_buffer("pe", sinusoidal(T, h))
        self.register_buffer("mask", graph_mask(embodiment, cfg.scene_tokens))
        self.encoder = nn.ModuleList(
            nn.TransformerEncoderLayer(
                h, cfg.heads, cfg.ff, cfg.dropout, batch_first=True, norm_first=True
            )
            for _ in range(cfg.enc_layers)
        )
        self.decoder = nn.ModuleList(
            nn.TransformerDecoderLayer(
                h, cfg.heads, cfg.ff, cfg.dropout, batch_first=True, norm_first=True
            )
            for _ in range(cfg.dec_layers)
        )
        self.query = nn.Parameter(torch.randn(1, 1, h) * 0.02)
        self.norm = nn.LayerNorm(h)
        self.head = nn.Linear(h, dof * cfg.modes)

    def layer_masked(self, i: int) -> bool:
        return self.masking == "all" or (self.masking == "interleaved" and i % 2 == 0)

    def encode(self, robot: Tensor, scene_tokens: Tensor, q: Tensor, goal: Tensor) -> Tensor:
        """The encoder's output tokens (B, T, H)."""
        b = self.backbone
        z_robot = b.robot_tokens(robot) + b.joints(q)[:, None] + b.joints(goal, True)[:, None]
        x = torch.cat([z_robot, scene_tokens.expand(len(q), -1, -1)], dim=1) + self.pe
        for i, layer in enumerate(self.encoder):
            x = layer(x, src_mask=self.mask if self.layer_masked(i) else None)
        return x

    def forward(self, robot: Tensor, scene_tokens: Tensor, q: Tensor, goal: Tensor) -> Tensor:
        memory = self.encode(robot, scene_tokens, q, goal)
        s = self.query.expand(len(q), -1, -1)
        for layer in self.decoder:
            s = layer(s, memory)
        return self.head(self.norm(s[:, 0]))


class MPNet(nn.Module):
    """MPNet's planning network: an MLP on the max-pooled scene embedding, q_t and q_goal,
    with dropout 0.5 kept on."""

    def __init__(self, cfg: ModelCfg, embodiment: Embodiment, dof: int) -> None:
        super().__init__()
        h = cfg.hidden
        self.backbone = _Backbone(cfg, embodiment, dof, robot_cloud=False)
        self.mlp = _mlp([3 * h, 8 * h, 4 * h, 2 * h, dof * cfg.modes], cfg.mlp_dropout)

    def forward(self, robot: Tensor, scene_tokens: Tensor, q: Tensor, goal: Tensor) -> Tensor:
        b = self.backbone
        scene = scene_tokens.amax(dim=1).expand(len(q), -1)
        return self.mlp(torch.cat([scene, b.joints(q), b.joints(goal)], dim=1))


class SimpNet(nn.Module):
    """SIMPNet-style message passing over the same embodiment graph (robot tokens linked
    along the chain, scene tokens sending to robot tokens), mean-aggregated messages with
    residual node updates, the robot nodes pooled into the step."""

    adj: Tensor

    def __init__(self, cfg: ModelCfg, embodiment: Embodiment, dof: int) -> None:
        super().__init__()
        h = cfg.hidden
        self.backbone = _Backbone(cfg, embodiment, dof)
        receives = ~graph_mask(embodiment, cfg.scene_tokens)  # [i, j]: i receives from j
        self.register_buffer("adj", receives.float() / receives.sum(1, keepdim=True))
        self.kr = embodiment.n_tokens
        # A message MLP on [x_i, x_j] whose first layer is split into its x_i and x_j parts,
        # and whose second (linear) layer is applied after the weighted sum over j: the same
        # function at a fraction of the (T x T) work.
        self.msg_i = nn.ModuleList(nn.Linear(h, h) for _ in range(cfg.enc_layers))
        self.msg_j = nn.ModuleList(nn.Linear(h, h, bias=False) for _ in range(cfg.enc_layers))
        self.msg_out = nn.ModuleList(nn.Linear(h, h) for _ in range(cfg.enc_layers))
        self.upd = nn.ModuleList(_mlp([2 * h, h, h]) for _ in range(cfg.enc_layers))
        self.norms = nn.ModuleList(nn.LayerNorm(h) for _ in range(cfg.enc_layers))
        self.drop = nn.Dropout(cfg.dropout)
        self.head = _mlp([2 * h, 2 * h, dof * cfg.modes], cfg.dropout)

    def forward(self, robot: Tensor, scene_tokens: Tensor, q: Tensor, goal: Tensor) -> Tensor:
        b = self.backbone
        zq = b.joints(q)
        zg = b.joints(goal, True)
        x = torch.cat(
            [
                b.robot_tokens(robot) + zq[:, None] + zg[:, None],
                scene_tokens.expand(len(q), -1, -1),
            ],
            dim=1,
        )
        layers = zip(self.msg_i, self.msg_j, self.msg_out, self.upd, self.norms, strict=True)
        for mi, mj, mo, upd, norm in layers:
            hidden = torch.relu(mi(x)[:, :, None] + mj(x)[:, None])  # (B, T, T, H)
            m = mo(torch.einsum("ij,bijh->bih", self.adj, hidden))
            x = norm(x + self.drop(upd(torch.cat([x, m], dim=-1))))
        pooled = torch.cat([x[:, : self.kr].mean(1), x[:, : self.kr].amax(1)], dim=-1)
        return self.head(pooled)


def build_model(kind: str, cfg: ModelCfg, embodiment: Embodiment, dof: int) -> nn.Module:
    if kind == "gaide":
        return Gaide(cfg, embodiment, dof, "interleaved")
    if kind == "gaide-v":
        return Gaide(cfg, embodiment, dof, "none")
    if kind == "gaide-h":
        return Gaide(cfg, embodiment, dof, "all")
    if kind == "mpnet":
        return MPNet(cfg, embodiment, dof)
    if kind == "simpnet":
        return SimpNet(cfg, embodiment, dof)
    raise ValueError(f"unknown model '{kind}'; valid: {list(MODEL_KINDS)}")


def encode_scene(model: nn.Module, scene: Tensor) -> Tensor:
    backbone: _Backbone = model.backbone  # type: ignore[assignment]
    return backbone.encode_scene(scene)
