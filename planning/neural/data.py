"""Training data: oracle paths on the training seed range, sharded, resumable, the same on any
machine.

Layout of a data directory::

    manifest.json          what was asked for and what each shard holds
    shard-00000.npz        paths [first, first + count) of the index range

Path index i is the problem of category ``categories[i % C]`` in scene ``s = i // C``: family
``families[s % F]`` at training seed ``split_seed("train", s // F)``
(:func:`~planning.families.generate_problem`). The C categories of a seed share its scene, so
one scene serves C start/goal pairs and is stored once per shard. A problem the oracle cannot
solve is left out and counted in the manifest.

A shard's npz holds ``worlds`` (uint8: the UTF-8 JSON list of the distinct scenes' obstacle
primitives, :meth:`PrimitiveWorld.to_dict`), ``scene_of`` (M,) int32 (each path's entry of
``worlds``), ``q`` (sum K, dof)
float32 waypoints of all paths back to back, ``offsets`` (M + 1,) int64 where each path
starts in ``q``, ``families`` (M,) int8 (index into the manifest's families), ``categories``
(M,) int8 (index into :data:`~planning.families.CATEGORIES`), ``seeds`` (M,) int64 and
``costs`` (M,) float64. Its bytes depend on (settings, shard index) only: the process pool
and a Ray cluster write identical files (:mod:`planning.neural.data_backends`). The robot
cloud at each q follows from FK and is not stored.

A scene's surface cloud (``scene_points`` points) is drawn from its world when the data is
loaded, with a generator seeded by (family, seed, the world's digest): the same points every
time, so storing the world (about 1 kB) instead of the cloud (24 kB) loses nothing and makes
a 50,000-path data set 30 MB instead of 250 MB. Format 2 (clouds stored, ``scenes`` (U, S,
3)) and format 1 (one scene per path, no categories) are still read.
"""

from __future__ import annotations

import hashlib
import io
import itertools
import json
import logging
import zipfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from gaide_core.errors import GaideError, ModelError
from planning.checker import CHECKERS, make_checker
from planning.families import generate_problem
from planning.family_names import CATEGORIES, FAMILIES, split_seed
from planning.oracle import OracleCfg, oracle_path
from planning.primitives import PrimitiveWorld
from planning.robot_model import RobotModel
from planning.scene_views import surface_cloud
from planning.sphere_model import SphereModel

log = logging.getLogger(__name__)

FORMAT = "gaide-data/3"
READABLE = ("gaide-data/1", "gaide-data/2", FORMAT)
MANIFEST = "manifest.json"


@dataclass(frozen=True)
class DataCfg:
    families: tuple[str, ...]
    paths: int  # path indices 0 .. paths-1 (some may fail)
    shard_size: int = 48  # a multiple of the categories keeps a scene in one shard
    max_step: float = 0.3  # rad, Euclidean joint step of the stored paths
    scene_points: int = 2048
    oracle: OracleCfg = field(default_factory=OracleCfg)  # budgeted by work, not time
    checker: str = "compiled"  # the oracle's collision checker backend
    categories: tuple[str, ...] = CATEGORIES  # cycled over the path indices of a scene

    def check(self) -> None:
        bad = [f for f in self.families if f not in FAMILIES]
        if bad or not self.families:
            raise ModelError(f"unknown families {bad}; valid: {list(FAMILIES)}")
        bad = [c for c in self.categories if c not in CATEGORIES]
        if bad or not self.categories or len(set(self.categories)) != len(self.categories):
            raise ModelError(f"categories must be distinct, among {list(CATEGORIES)}; got {bad}")
        if self.paths < 1 or self.shard_size < 1:
            raise ModelError(
                f"need paths >= 1 and shard_size >= 1; got {self.paths}, {self.shard_size}"
            )
        if not (0 < self.max_step <= 1.0) or self.scene_points < 64:
            raise ModelError(
                "need 0 < max_step <= 1 rad and scene_points >= 64; got "
                f"{self.max_step}, {self.scene_points}"
            )
        if self.checker not in CHECKERS:
            raise ModelError(f"unknown checker '{self.checker}'; valid: {list(CHECKERS)}")

    def settings(self) -> dict[str, Any]:
        """The settings as the manifest stores them (JSON types)."""
        return json.loads(json.dumps(asdict(self)))

    def problem_of(self, index: int) -> tuple[str, int, str]:
        """(family, training seed, category) of path ``index``."""
        per = len(self.categories)
        scene = index // per
        fam = self.families[scene % len(self.families)]
        return fam, split_seed("train", scene // len(self.families)), self.categories[index % per]

    def shards(self) -> int:
        return -(-self.paths // self.shard_size)


def shard_name(k: int) -> str:
    return f"shard-{k:05d}.npz"


@dataclass(frozen=True)
class PathRow:
    scene_key: str  # the scene's identity: family, seed and a digest of its obstacles
    world: str  # the scene's obstacles: canonical JSON of PrimitiveWorld.to_dict()
    path: npt.NDArray[np.float32]  # (K, dof) rad
    family: int
    category: int
    seed: int
    cost: float  # rad


def one_path(cfg: DataCfg, index: int, robot: RobotModel, spheres: SphereModel) -> PathRow | str:
    """Path ``index`` (module docstring), or why it failed."""
    fam, seed, category = cfg.problem_of(index)
    rng = np.random.default_rng([index, seed])
    try:
        problem = generate_problem(fam, seed, robot, spheres, category=category)
    except GaideError as err:
        return f"{fam} seed {seed} {category}: {err}"
    checker = make_checker(robot, spheres, problem.world, backend=cfg.checker)
    oracle = replace(cfg.oracle, max_step=cfg.max_step)  # labels at the data's step
    res = oracle_path(checker, problem.start, problem.goal, rng, oracle)
    if res.path is None:
        return f"{fam} seed {seed} {category}: oracle {res.status.value}: {res.detail}"
    world = world_json(problem.world.to_dict())
    return PathRow(
        scene_key=f"{fam}/{seed}/{world_digest(world)}",
        world=world,
        path=res.path.astype(np.float32),
        family=cfg.families.index(fam),
        category=CATEGORIES.index(category),
        seed=seed,
        cost=res.cost,
    )


def world_json(world: Any) -> str:
    """Canonical JSON of a world's ``to_dict()``: the same text for the same world."""
    return json.dumps(world, sort_keys=True, separators=(",", ":"))


def world_digest(world: str) -> str:
    """16 hex digits identifying a world (of its canonical JSON)."""
    return hashlib.sha256(world.encode()).hexdigest()[:16]


def scene_cloud(world: str, family: str, seed: int, points: int) -> npt.NDArray[np.float32]:
    """The (points, 3) surface cloud of a stored scene: the same on every load."""
    rng = np.random.default_rng(
        [FAMILIES.index(family), seed, int(world_digest(world), 16) % 2**32]
    )
    return surface_cloud(PrimitiveWorld.from_dict(json.loads(world)), points, rng).astype(
        np.float32
    )


def make_shard(
    cfg: DataCfg, k: int, robot: RobotModel, spheres: SphereModel
) -> tuple[bytes, dict[str, Any]]:
    """Shard ``k``: its npz bytes (the same for the same settings, whoever makes it) and its
    manifest entry."""
    first = k * cfg.shard_size
    count = min(cfg.shard_size, cfg.paths - first)
    rows: list[PathRow] = []
    failures: list[str] = []
    for i in range(first, first + count):
        r = one_path(cfg, i, robot, spheres)
        if isinstance(r, str):
            failures.append(r)
        else:
            rows.append(r)
    entry = {
        "file": shard_name(k),
        "first": first,
        "count": count,
        "paths": len(rows),
        "failures": failures,
    }
    return shard_bytes(rows, robot.dof), entry


def shard_bytes(rows: list[PathRow], dof: int) -> bytes:
    """The npz of ``rows``, byte for byte the same for the same rows (no time stamps)."""
    keys = list(dict.fromkeys(r.scene_key for r in rows))
    paths = [r.path for r in rows]
    worlds = [next(r.world for r in rows if r.scene_key == key) for key in keys]
    arrays = {
        "worlds": np.frombuffer(json.dumps(worlds).encode(), np.uint8),
        "scene_of": np.array([keys.index(r.scene_key) for r in rows], np.int32),
        "q": np.concatenate(paths) if rows else np.zeros((0, dof), np.float32),
        "offsets": np.concatenate([[0], np.cumsum([len(p) for p in paths])]).astype(np.int64),
        "families": np.array([r.family for r in rows], np.int8),
        "categories": np.array([r.category for r in rows], np.int8),
        "seeds": np.array([r.seed for r in rows], np.int64),
        "costs": np.array([r.cost for r in rows], np.float64),
    }
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, a in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.ascontiguousarray(a), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            z.writestr(info, member.getvalue(), zipfile.ZIP_DEFLATED)
    return buf.getvalue()


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
    if not isinstance(manifest, dict) or manifest.get("format") not in READABLE:
        raise ModelError(f"{p}: not a {FORMAT} manifest")
    return manifest


@dataclass
class PathSet:
    """All paths of a data directory: ``scenes`` (U, S, 3), ``paths`` (list of (K, dof)),
    each path's scene row ``scene_of``, family and category."""

    scenes: npt.NDArray[np.float32]
    scene_of: npt.NDArray[np.int64]
    paths: list[npt.NDArray[np.float32]]
    families: npt.NDArray[np.int8]
    categories: npt.NDArray[np.int8]  # -1: unknown (format 1)
    family_names: tuple[str, ...]
    max_step: float


def _shard_scenes(z: Any, families: tuple[str, ...], points: int) -> npt.NDArray[np.float32]:
    """(U, S, 3) clouds of a shard's scenes: stored (formats 1, 2) or drawn from its worlds."""
    if "scenes" in z:
        return np.asarray(z["scenes"], np.float32)
    worlds = json.loads(bytes(z["worlds"]).decode())
    scene_of, fams, seeds = z["scene_of"], z["families"], z["seeds"]
    clouds = []
    for u, world in enumerate(worlds):
        row = int(np.flatnonzero(scene_of == u)[0])
        clouds.append(scene_cloud(world, families[int(fams[row])], int(seeds[row]), points))
    return np.stack(clouds)


def load_paths(path: str | Path, progress: Callable[[int, int], None] | None = None) -> PathSet:
    """Every path of the data directory ``path``, with its scene's cloud (drawn here);
    ``progress(done, total)`` after each shard (a 50,000-path set takes tens of seconds)."""
    manifest = read_manifest(path)
    families = tuple(manifest["settings"]["families"])
    points = int(manifest["settings"]["scene_points"])
    scenes, scene_of, paths, fams, cats = [], [], [], [], []
    rows = 0
    for done, s in enumerate(manifest["shards"], 1):
        if progress is not None:
            progress(done - 1, len(manifest["shards"]))
        f = Path(path) / s["file"]
        try:
            with np.load(f) as z:
                if s["paths"] == 0:
                    continue
                shard_scenes = _shard_scenes(z, families, points)
                scenes.append(shard_scenes)
                n = len(z["offsets"]) - 1
                own = z["scene_of"].astype(np.int64) if "scene_of" in z else np.arange(n)
                scene_of.append(own + rows)
                rows += len(shard_scenes)
                off, q = z["offsets"], z["q"]
                paths += [q[a:b] for a, b in itertools.pairwise(off)]
                fams.append(z["families"])
                cats.append(z["categories"] if "categories" in z else np.full(n, -1, np.int8))
        except (OSError, ValueError, KeyError, IndexError, GaideError) as err:
            raise ModelError(
                f"{f}: corrupt or missing shard ({err}); delete it and run `gaide data generate` again to remake it"
            ) from err
    if progress is not None:
        progress(len(manifest["shards"]), len(manifest["shards"]))
    if not paths:
        raise ModelError(f"{path}: the data set holds no paths")
    return PathSet(
        scenes=np.concatenate(scenes),
        scene_of=np.concatenate(scene_of),
        paths=paths,
        families=np.concatenate(fams),
        categories=np.concatenate(cats),
        family_names=families,
        max_step=float(manifest["settings"]["max_step"]),
    )
