"""Training data: oracle paths on the training seed range, sharded and resumable.

Layout of a data directory::

    manifest.json          what was asked for and what each shard holds
    shard-00000.npz        paths [first, first + count) of the index range

A shard's npz holds ``scenes`` (M, S, 3) float32 surface clouds (base frame, m), ``q``
(sum K, dof) float32 waypoints of all paths back to back, ``offsets`` (M + 1,) int64 where
each path starts in ``q``, ``families`` (M,) int8 (index into the manifest's families),
``seeds`` (M,) int64 and ``costs`` (M,) float64. Path index i of the range is the problem of
family ``families[i % F]`` at training seed ``split_seed("train", i // F)``; a problem the
oracle cannot solve is left out and counted in the manifest. The robot cloud at each q
follows from FK and is not stored.
"""

from __future__ import annotations

import io
import itertools
import json
import logging
import math
import multiprocessing
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from core.atomic import write_bytes_atomic
from core.errors import GaideError, ModelError
from planning.checker import make_checker
from planning.families import FAMILIES, generate_problem, split_seed
from planning.oracle import OracleCfg, oracle_path
from planning.robot_model import RobotModel
from planning.scene_views import surface_cloud
from planning.sphere_model import SphereModel

log = logging.getLogger(__name__)

FORMAT = "gaide-data/1"
MANIFEST = "manifest.json"


@dataclass(frozen=True)
class DataCfg:
    families: tuple[str, ...]
    paths: int  # path indices 0 .. paths-1 (some may fail)
    shard_size: int = 50
    max_step: float = 0.3  # rad, Euclidean joint step of the stored paths
    scene_points: int = 2048
    oracle: OracleCfg = field(default_factory=OracleCfg)  # budgeted by work, not time
    checker: str = "compiled"  # the oracle's collision checker backend

    def check(self) -> None:
        bad = [f for f in self.families if f not in FAMILIES]
        if bad or not self.families:
            raise ModelError(f"unknown families {bad}; valid: {list(FAMILIES)}")
        if self.paths < 1 or self.shard_size < 1:
            raise ModelError(
                f"need paths >= 1 and shard_size >= 1; got {self.paths}, {self.shard_size}"
            )
        if not (0 < self.max_step <= 1.0) or self.scene_points < 64:
            raise ModelError(
                "need 0 < max_step <= 1 rad and scene_points >= 64; got "
                f"{self.max_step}, {self.scene_points}"
            )


def shard_name(k: int) -> str:
    return f"shard-{k:05d}.npz"


def one_path(
    cfg: DataCfg, index: int, robot: RobotModel, spheres: SphereModel
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], int, int, float] | str:
    """(scene cloud, path, family index, seed, cost) of path ``index``, or why it failed."""
    F = len(cfg.families)
    fam = cfg.families[index % F]
    seed = split_seed("train", index // F)
    rng = np.random.default_rng([index, seed])
    try:
        problem = generate_problem(fam, seed, robot, spheres)
    except GaideError as err:
        return f"{fam} seed {seed}: {err}"
    checker = make_checker(robot, spheres, problem.world, backend=cfg.checker)
    oracle = replace(cfg.oracle, max_step=cfg.max_step)  # labels at the data's step
    res = oracle_path(checker, problem.start, problem.goal, rng, oracle)
    if res.path is None:
        return f"{fam} seed {seed}: oracle {res.status.value}: {res.detail}"
    cloud = surface_cloud(problem.world, cfg.scene_points, rng)
    return (
        cloud.astype(np.float32),
        res.path.astype(np.float32),
        cfg.families.index(fam),
        seed,
        res.cost,
    )


def _shard_bytes(rows: list[Any]) -> bytes:
    buf = io.BytesIO()
    paths = [r[1] for r in rows]
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in paths])]).astype(np.int64)
    np.savez_compressed(
        buf,
        scenes=np.stack([r[0] for r in rows]) if rows else np.zeros((0, 0, 3), np.float32),
        q=np.concatenate(paths) if rows else np.zeros((0, 0), np.float32),
        offsets=offsets,
        families=np.array([r[2] for r in rows], np.int8),
        seeds=np.array([r[3] for r in rows], np.int64),
        costs=np.array([r[4] for r in rows], np.float64),
    )
    return buf.getvalue()


_WORKER: dict[str, Any] = {}


def _init_worker(robot_config: str | None) -> None:
    import torch

    torch.set_num_threads(1)
    from ompl import util as ou

    ou.setLogLevel(ou.LogLevel.LOG_NONE)  # AORRTC reports every straight-edge solution
    from planning.robot_setup import robot_and_spheres

    _WORKER["robot"], _WORKER["spheres"] = robot_and_spheres(robot_config)


def _make_shard(args: tuple[DataCfg, int, str]) -> dict[str, Any]:
    cfg, k, out = args
    first = k * cfg.shard_size
    count = min(cfg.shard_size, cfg.paths - first)
    rows, failures = [], []
    for i in range(first, first + count):
        r = one_path(cfg, i, _WORKER["robot"], _WORKER["spheres"])
        if isinstance(r, str):
            failures.append(r)
        else:
            rows.append(r)
    write_bytes_atomic(Path(out) / shard_name(k), _shard_bytes(rows), ModelError)
    return {
        "file": shard_name(k),
        "first": first,
        "count": count,
        "paths": len(rows),
        "failures": failures,
    }


def generate(
    cfg: DataCfg,
    out: str | Path,
    *,
    robot_config: str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Make (or finish) the data set in ``out``; returns the manifest. Shards already on
    disk with the same settings are kept, so an interrupted run resumes."""
    cfg.check()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    settings = json.loads(json.dumps(asdict(cfg)))  # tuples as lists, as the manifest reads
    settings["robot_config"] = robot_config
    manifest_path = out / MANIFEST
    done: dict[str, dict[str, Any]] = {}
    if manifest_path.exists():
        old = read_manifest(out)
        if old["settings"] != settings:
            raise ModelError(
                f"{out} holds data made with other settings ({old['settings']}); use another "
                "directory or the same settings to resume"
            )
        done = {s["file"]: s for s in old["shards"] if (out / s["file"]).exists()}
    n_shards = math.ceil(cfg.paths / cfg.shard_size)
    todo = [k for k in range(n_shards) if shard_name(k) not in done]
    workers = workers or os.cpu_count() or 1
    shards = dict(done)

    def save() -> dict[str, Any]:
        listed = sorted(shards.values(), key=lambda s: s["first"])
        manifest = {
            "format": FORMAT,
            "settings": settings,
            "complete": len(listed) == n_shards,
            "paths": sum(s["paths"] for s in listed),
            "failures": sum(len(s["failures"]) for s in listed),
            "shards": listed,
        }
        write_bytes_atomic(manifest_path, json.dumps(manifest, indent=1).encode(), ModelError)
        return manifest

    manifest = save()
    jobs = [(cfg, k, str(out)) for k in todo]
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(min(workers, max(len(jobs), 1)), _init_worker, (robot_config,)) as pool:
        for i, shard in enumerate(pool.imap_unordered(_make_shard, jobs)):
            shards[shard["file"]] = shard
            manifest = save()
            if progress:
                progress(i + 1, len(jobs))
    return manifest


def read_manifest(path: str | Path) -> dict[str, Any]:
    p = Path(path) / MANIFEST
    try:
        manifest = json.loads(p.read_text())
    except FileNotFoundError as err:
        raise ModelError(
            f"{path} is not a data directory: no {MANIFEST} (make one with `gaide data generate`)"
        ) from err
    except (OSError, ValueError) as err:
        raise ModelError(f"{p}: unreadable manifest ({err})") from err
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise ModelError(f"{p}: not a {FORMAT} manifest")
    return manifest


@dataclass
class PathSet:
    """All paths of a data directory: ``scenes`` (M, S, 3), ``paths`` list of (K, dof)."""

    scenes: npt.NDArray[np.float32]
    paths: list[npt.NDArray[np.float32]]
    families: npt.NDArray[np.int8]
    family_names: tuple[str, ...]
    max_step: float


def load_paths(path: str | Path) -> PathSet:
    manifest = read_manifest(path)
    scenes, paths, fams = [], [], []
    for s in manifest["shards"]:
        f = Path(path) / s["file"]
        try:
            with np.load(f) as z:
                if s["paths"] == 0:
                    continue
                scenes.append(z["scenes"])
                off = z["offsets"]
                q = z["q"]
                paths += [q[a:b] for a, b in itertools.pairwise(off)]
                fams.append(z["families"])
        except (OSError, ValueError, KeyError) as err:
            raise ModelError(
                f"{f}: corrupt or missing shard ({err}); delete it and run `gaide data generate` again to remake it"
            ) from err
    if not paths:
        raise ModelError(f"{path}: the data set holds no paths")
    return PathSet(
        scenes=np.concatenate(scenes),
        paths=paths,
        families=np.concatenate(fams),
        family_names=tuple(manifest["settings"]["families"]),
        max_step=float(manifest["settings"]["max_step"]),
    )
