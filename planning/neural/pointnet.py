"""PointNet++ set abstraction (Qi et al., 2017) in plain torch: farthest point sampling,
ball query, a shared MLP on each group, max-pooling.

Written here because no maintained library ships it without compiled CUDA extensions
(torch_cluster / pointnet2_ops need a toolchain and a GPU build); these few batched tensor
operations run on CPU and GPU alike.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn


def farthest_point_sample(xyz: Tensor, k: int) -> Tensor:
    """Indices (B, k) of ``k`` points of ``xyz`` (B, N, 3) picked by farthest point sampling,
    starting from point 0 (deterministic)."""
    B, N, _ = xyz.shape
    if k > N:
        raise ValueError(f"cannot pick {k} points out of {N}")
    idx = torch.zeros(B, k, dtype=torch.long, device=xyz.device)
    nearest = torch.full((B, N), float("inf"), device=xyz.device, dtype=xyz.dtype)
    last = torch.zeros(B, dtype=torch.long, device=xyz.device)
    rows = torch.arange(B, device=xyz.device)
    for i in range(k):
        idx[:, i] = last
        d = ((xyz - xyz[rows, last][:, None, :]) ** 2).sum(-1)
        nearest = torch.minimum(nearest, d)
        last = nearest.argmax(dim=1)
    return idx


def ball_query(xyz: Tensor, centres: Tensor, radius: float, nsample: int) -> Tensor:
    """Indices (B, k, nsample) of the ``nsample`` points of ``xyz`` (B, N, 3) nearest to each
    of ``centres`` (B, k, 3) within ``radius``; a group with fewer points repeats its nearest
    one (a centre is a cloud point, so every group has one)."""
    d = torch.cdist(centres, xyz)  # (B, k, N)
    n = min(nsample, xyz.shape[1])
    dist, idx = d.topk(n, dim=-1, largest=False)
    return torch.where(dist <= radius, idx, idx[..., :1])


def gather(points: Tensor, idx: Tensor) -> Tensor:
    """``points`` (B, N, C) at ``idx`` (B, ...) -> (B, ..., C)."""
    B = points.shape[0]
    flat = idx.reshape(B, -1)
    out = torch.gather(points, 1, flat[..., None].expand(-1, -1, points.shape[-1]))
    return out.reshape(*idx.shape, points.shape[-1])


class SetAbstraction(nn.Module):
    """One set-abstraction level: ``k`` centres (farthest point sampling unless given), a
    ball of ``radius`` with ``nsample`` points around each, a shared MLP on the points'
    offsets from their centre (scaled by the radius), max-pooled into one token per centre.
    The centre's own position is embedded and added, so a token knows where it is."""

    def __init__(self, k: int, radius: float, nsample: int, widths: tuple[int, ...]) -> None:
        super().__init__()
        self.k, self.radius, self.nsample = k, float(radius), nsample
        layers: list[nn.Module] = []
        prev = 3
        for w in widths:
            layers += [nn.Linear(prev, w), nn.LayerNorm(w), nn.ReLU()]
            prev = w
        self.mlp = nn.Sequential(*layers)
        self.where = nn.Sequential(nn.Linear(3, prev), nn.ReLU(), nn.Linear(prev, prev))
        self.out_dim = prev

    def forward(self, xyz: Tensor, centre_idx: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Tokens (B, k, C) and their centres (B, k, 3) of the cloud ``xyz`` (B, N, 3);
        ``centre_idx`` (B, k) or (k,) fixes the centres instead of sampling them."""
        if centre_idx is None:
            centre_idx = farthest_point_sample(xyz, self.k)
        elif centre_idx.dim() == 1:
            centre_idx = centre_idx[None].expand(xyz.shape[0], -1)
        centres = gather(xyz, centre_idx)  # (B, k, 3)
        groups = gather(xyz, ball_query(xyz, centres, self.radius, self.nsample))
        local = (groups - centres[:, :, None, :]) / self.radius  # (B, k, s, 3)
        tokens = self.mlp(local).amax(dim=2)
        return tokens + self.where(centres), centres
