"""The robot as the network sees it: points on each link's collision mesh, carried by forward
kinematics, grouped into tokens that each belong to one link, and the embodiment graph that
links those tokens.

The token centres are fixed points of the links (farthest point sampling within each link,
once), so every token keeps its link at every configuration and the graph mask is a constant
of the robot. Every link with geometry gets at least one token.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import trimesh

from gaide_core.errors import RobotModelError
from gaide_core.types import Array
from planning.kinematics import BatchKinematics
from planning.robot_model import RobotModel


@dataclass(frozen=True)
class Embodiment:
    """``local`` (P, 3): points in their joint's frame; ``joint_ids`` (P,); ``point_link``
    (P,) link index of each point; ``token_idx`` (K,) the points that are token centres;
    ``token_link`` (K,) their links; ``links`` the link names; ``adjacency`` (L, L) True where
    two links are the same or neighbours in the kinematic chain."""

    links: tuple[str, ...]
    local: Array
    joint_ids: npt.NDArray[np.int64]
    point_link: npt.NDArray[np.int64]
    token_idx: npt.NDArray[np.int64]
    token_link: npt.NDArray[np.int64]
    adjacency: npt.NDArray[np.bool_]

    @property
    def n_points(self) -> int:
        return len(self.local)

    @property
    def n_tokens(self) -> int:
        return len(self.token_idx)

    def token_graph(self) -> npt.NDArray[np.bool_]:
        """(K, K) True where robot tokens i and j are linked (same or adjacent links)."""
        return self.adjacency[self.token_link][:, self.token_link]

    def to_dict(self) -> dict[str, Any]:
        return {
            "links": list(self.links),
            "local": self.local.tolist(),
            "joint_ids": self.joint_ids.tolist(),
            "point_link": self.point_link.tolist(),
            "token_idx": self.token_idx.tolist(),
            "token_link": self.token_link.tolist(),
            "adjacency": self.adjacency.tolist(),
        }

    @staticmethod
    def from_dict(d: dict[str, Any]) -> Embodiment:
        return Embodiment(
            links=tuple(d["links"]),
            local=np.asarray(d["local"], float),
            joint_ids=np.asarray(d["joint_ids"], np.int64),
            point_link=np.asarray(d["point_link"], np.int64),
            token_idx=np.asarray(d["token_idx"], np.int64),
            token_link=np.asarray(d["token_link"], np.int64),
            adjacency=np.asarray(d["adjacency"], bool),
        )


def _fps(points: Array, k: int) -> npt.NDArray[np.int64]:
    """Farthest point sampling of k indices of ``points`` (N, 3), from the first point."""
    idx = [0]
    d = np.linalg.norm(points - points[0], axis=1)
    for _ in range(k - 1):
        i = int(d.argmax())
        idx.append(i)
        d = np.minimum(d, np.linalg.norm(points - points[i], axis=1))
    return np.asarray(idx, np.int64)


def build_embodiment(
    robot: RobotModel, n_points: int = 256, n_tokens: int = 16, seed: int = 0
) -> Embodiment:
    """Sample ``n_points`` surface points over the links' collision meshes (by area, at least
    ``n_tokens``-worth spread so every link has a token) and pick ``n_tokens`` centres."""
    meshes = robot.link_meshes
    names = tuple(n for n in robot.links if n in meshes)
    if not names:
        raise RobotModelError("the robot has no link with collision geometry")
    if n_tokens < len(names) or n_points < 2 * n_tokens:
        raise RobotModelError(
            f"need n_tokens >= {len(names)} (one per link with geometry) and "
            f"n_points >= 2 * n_tokens; got {n_tokens} tokens, {n_points} points"
        )
    areas = np.array([meshes[n].area for n in names])
    share = areas / areas.sum()
    tokens = 1 + np.floor(share * (n_tokens - len(names))).astype(int)
    tokens[np.argsort(-share)[: n_tokens - tokens.sum()]] += 1
    points = np.maximum(np.floor(share * n_points).astype(int), 2 * tokens)
    points[np.argmax(share)] += n_points - points.sum()
    rng = np.random.default_rng(seed)
    local, joint_ids, point_link, token_idx = [], [], [], []
    offset = 0
    for li, name in enumerate(names):
        link = robot.links[name]
        pts, _ = trimesh.sample.sample_surface(
            meshes[name], int(points[li]), seed=int(rng.integers(2**31))
        )
        in_joint = pts @ link.T_joint_link[:3, :3].T + link.T_joint_link[:3, 3]
        local.append(in_joint)
        joint_ids.append(np.full(len(pts), link.joint_id))
        point_link.append(np.full(len(pts), li))
        token_idx.append(offset + _fps(pts, int(tokens[li])))
        offset += len(pts)
    adjacency = np.array([[robot.chain_adjacent(a, b) for b in names] for a in names], bool)
    tidx = np.concatenate(token_idx)
    plink = np.concatenate(point_link)
    return Embodiment(
        links=names,
        local=np.concatenate(local),
        joint_ids=np.concatenate(joint_ids).astype(np.int64),
        point_link=plink.astype(np.int64),
        token_idx=tidx,
        token_link=plink[tidx].astype(np.int64),
        adjacency=adjacency,
    )


class RobotCloud:
    """Robot point clouds (B, P, 3) in the base frame for batches of configurations."""

    def __init__(self, robot: RobotModel, embodiment: Embodiment) -> None:
        self.embodiment = embodiment
        self._fk = BatchKinematics(robot)
        self._base_inv = np.linalg.inv(robot.T_world_base)

    def __call__(self, Q: Array) -> Array:
        Q = np.atleast_2d(np.asarray(Q, float))
        e = self.embodiment
        pts = self._fk.points(Q, e.joint_ids, e.local)  # world frame
        return pts @ self._base_inv[:3, :3].T + self._base_inv[:3, 3]
