"""Making a data set's shards: on this machine's processes, or as Ray tasks on a cluster.

Either way a shard is :func:`planning.neural.data.make_shard` of (settings, index), computed
where the work runs and written here, by index, atomically, with the manifest rewritten after
each one: an interrupted run resumes, and a shard's bytes do not depend on who made it.
Workers load the robot themselves (the robot config must exist at the same path on every Ray
node: the project installed the same way).
"""

from __future__ import annotations

import json
import logging
import multiprocessing
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import ModelError
from planning.neural.data import FORMAT, MANIFEST, DataCfg, make_shard, read_manifest, shard_name

log = logging.getLogger(__name__)

Shard = tuple[bytes, dict[str, Any]]

_WORKER: dict[str, Any] = {}


def _worker_robot(robot_config: str | None) -> tuple[Any, Any]:
    """The robot and spheres of this worker process (loaded once)."""
    if _WORKER.get("config", ()) != robot_config:
        import torch
        from threadpoolctl import threadpool_limits

        # A worker is one CPU's share of the work (a process of the pool, a Ray task of one
        # CPU): more threads in torch or BLAS only oversubscribe the cores.
        torch.set_num_threads(1)
        threadpool_limits(1)
        from ompl import util as ou

        ou.setLogLevel(ou.LogLevel.LOG_NONE)
        from planning.robot_setup import robot_and_spheres

        _WORKER["robot"], _WORKER["spheres"] = robot_and_spheres(robot_config)
        _WORKER["config"] = robot_config
    return _WORKER["robot"], _WORKER["spheres"]


def _shard_job(args: tuple[DataCfg, int, str | None]) -> Shard:
    cfg, k, robot_config = args
    return make_shard(cfg, k, *_worker_robot(robot_config))


def _local(
    cfg: DataCfg, todo: list[int], robot_config: str | None, workers: int
) -> Iterator[Shard]:
    ctx = multiprocessing.get_context("fork")
    jobs = [(cfg, k, robot_config) for k in todo]
    with ctx.Pool(min(workers, max(len(jobs), 1))) as pool:
        yield from pool.imap_unordered(_shard_job, jobs)


def _ray(cfg: DataCfg, todo: list[int], robot_config: str | None, address: str) -> Iterator[Shard]:
    """Shards as Ray tasks (one CPU each). ``address``: ``auto`` joins the running cluster
    (RAY_ADDRESS or a local one) and starts a local instance when there is none; anything else
    is a cluster address."""
    try:
        import ray
    except ImportError as err:  # pragma: no cover - ray is a dependency
        raise ModelError("--ray needs the ray package: pip install ray") from err
    started = False
    if not ray.is_initialized():
        try:
            ray.init(address=address, log_to_driver=False)
        except ConnectionError:
            if address != "auto":
                raise ModelError(f"no Ray cluster answers at {address}") from None
            log.info("no running Ray cluster: starting a local one")
            ray.init(log_to_driver=False, include_dashboard=False)
        started = True
    try:
        task = ray.remote(num_cpus=1)(_shard_job)
        pending = [task.remote((cfg, k, robot_config)) for k in todo]
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        if started:
            ray.shutdown()


def generate(
    cfg: DataCfg,
    out: str | Path,
    *,
    robot_config: str | None = None,
    workers: int | None = None,
    ray: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Make (or finish) the data set in ``out``; returns the manifest. Shards already on
    disk with the same settings are kept, so an interrupted run resumes. ``ray``: a Ray
    cluster address (or ``auto``) to run the shards on, instead of ``workers`` processes."""
    cfg.check()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    settings = cfg.settings()
    settings["robot_config"] = robot_config
    manifest_path = out / MANIFEST
    done: dict[str, dict[str, Any]] = {}
    if manifest_path.exists():
        old = read_manifest(out)
        # Manifests written before the oracle had a tie share, an extra clearance or the band
        # were made without them, and those before the per-sphere clearance rule with the
        # tightest sphere's (which only a clearance makes a difference to).
        old_oracle = old["settings"].get("oracle")
        if isinstance(old_oracle, dict):
            old_oracle.setdefault("tie", 0.0)
            old_oracle.setdefault("clearance", 0.0)
            old_oracle.setdefault("band", 0)
            old_oracle.setdefault("band_pull", False)
            rule = "tightest" if old_oracle["clearance"] > 0 else "sphere"
            old_oracle.setdefault("clearance_rule", rule)
        if old["settings"] != settings or old["format"] != FORMAT:
            raise ModelError(
                f"{out} holds data made with other settings ({old['settings']}); use another "
                "directory or the same settings to resume"
            )
        done = {s["file"]: s for s in old["shards"] if (out / s["file"]).exists()}
    n_shards = cfg.shards()
    todo = [k for k in range(n_shards) if shard_name(k) not in done]
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
    made = (
        _ray(cfg, todo, robot_config, ray)
        if ray is not None
        else _local(cfg, todo, robot_config, workers or os.cpu_count() or 1)
    )
    for i, (payload, entry) in enumerate(made):
        write_bytes_atomic(out / entry["file"], payload, ModelError)
        shards[entry["file"]] = entry
        manifest = save()
        if progress:
            progress(i + 1, len(todo))
    return manifest
