"""``gaide bench collision``: speed and trustworthiness of the sphere collision checker.

Figures (all from one run, the compiled checker unless ``checker="numpy"``; one process):
- ``configs_per_s_cloud`` / ``configs_per_s_primitives``: validity checks per second, batch of
  10,000 uniform configurations, against a 50,000-point cloud / 20 analytic primitives,
  median of the repeats.
- ``single_call_us``: one configuration checked from Python (``config_valid_one``, what a
  per-state callback such as OMPL's makes), median; ``single_batch_call_us`` the same
  through ``config_valid`` on a (1, dof) batch.
- ``edges_per_s``: edges of 1 rad (joint-space length, random directions, from valid
  configurations) certified against the cloud, each checked to its end or to its first
  collision; ``edges_per_s_primitives`` the same against the primitives.
- ``agreement``: share of the configurations and edges above (both worlds) on which the
  compiled checker and the numpy reference agree (must be 1.0).
- ``fk_max_err_m``: the checker's sphere-centre FK versus Pinocchio, float64.
- ``mesh_missed``: configurations the PyBullet mesh reference finds touching the world but the
  sphere checker calls free, over both worlds, out of ``mesh_samples`` configurations near the
  obstacles (sphere clearance below ``near_band_m``; colliding ones included).
- ``mesh_false_alarm_rate``: of the configurations the meshes find free, the share the spheres
  flag (primitives world; ``..._cloud`` for the cloud world).
- ``machine``: the CPU, its widest SIMD, the cores and the compiler's versions: the rates
  above are the machine's as much as the code's (docs/results.md: the same build measured a
  third slower on another machine).
"""

from __future__ import annotations

import logging
import os
import platform
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaide_core.transforms import from_xyz_rpy
from gaide_core.types import Array
from planning.checker import make_checker
from planning.collision import CollisionChecker, SphereCollisionChecker
from planning.distance_field import CloudWorld
from planning.kinematics import reference_points
from planning.primitives import Box, Cylinder, Primitive, PrimitiveWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class CollisionBenchCfg:
    batch: int = 10_000  # configurations per validity batch
    cloud_points: int = 50_000
    voxel: float = 0.01  # m, distance-field lattice
    edges: int = 300  # 1 rad edges timed
    mesh_samples: int = 10_000  # configurations compared with the mesh reference
    near_band: float = 0.10  # m, "near the obstacles"
    repeats: int = 5
    seed: int = 0
    checker: str = "compiled"  # the backend measured; agreement is always against numpy
    single_calls: int = 20_000  # one-configuration calls timed


def benchmark_workcell(rng: np.random.Generator) -> list[Primitive]:
    """20 primitives around a UR5 on a table: table top 2 cm below the base (an adapter
    plate), a two-board shelf, boxes and cylinders in reach."""
    prims: list[Primitive] = [
        Box(np.array([1.6, 1.6, 0.04]), from_xyz_rpy([0.2, 0, -0.04], [0, 0, 0]))
    ]
    # shelf: two sides, two boards, back
    x = 0.75
    prims += [
        Box(np.array([0.30, 0.02, 0.9]), from_xyz_rpy([x, -0.4, 0.43], [0, 0, 0])),
        Box(np.array([0.30, 0.02, 0.9]), from_xyz_rpy([x, 0.4, 0.43], [0, 0, 0])),
        Box(np.array([0.30, 0.80, 0.02]), from_xyz_rpy([x, 0.0, 0.35], [0, 0, 0])),
        Box(np.array([0.30, 0.80, 0.02]), from_xyz_rpy([x, 0.0, 0.70], [0, 0, 0])),
        Box(np.array([0.02, 0.80, 0.9]), from_xyz_rpy([x + 0.16, 0.0, 0.43], [0, 0, 0])),
    ]
    while len(prims) < 20:
        r = rng.uniform(0.35, 0.8)
        a = rng.uniform(-np.pi, np.pi)
        xy = [r * np.cos(a), r * np.sin(a)]
        if xy[0] > 0.55 and abs(xy[1]) < 0.5:
            continue  # keep the shelf clear
        if len(prims) % 3 == 0:
            h = rng.uniform(0.1, 0.3)
            prims.append(
                Cylinder(
                    float(rng.uniform(0.03, 0.07)), h, from_xyz_rpy([*xy, h / 2 - 0.02], [0, 0, 0])
                )
            )
        else:
            size = rng.uniform([0.05, 0.05, 0.05], [0.2, 0.2, 0.3])
            prims.append(Box(size, from_xyz_rpy([*xy, size[2] / 2 - 0.02], [0, 0, a])))
    return prims


def _single_call_us(checker: CollisionChecker, Q: Array, n: int) -> dict[str, float]:
    """Median microseconds of one configuration checked from Python, per-state call and
    (1, dof) batch call, over ``n`` calls each."""
    rows = [np.ascontiguousarray(q) for q in Q[: min(n, len(Q))]]
    out = {}
    for key, call in (
        ("single_call_us", checker.config_valid_one),
        ("single_batch_call_us", lambda q: checker.config_valid(q[None])),
    ):
        times = np.empty(len(rows))
        for k, q in enumerate(rows):
            t0 = time.perf_counter()
            call(q)
            times[k] = time.perf_counter() - t0
        out[key] = float(np.median(times) * 1e6)
    return out


def _agreement(
    robot: RobotModel,
    spheres: SphereModel,
    Q: Array,
    edges: dict[str, tuple[Array, Array]],
    cloud: tuple[Any, CollisionChecker],
    prims: tuple[Any, CollisionChecker],
) -> dict[str, Any]:
    """Share of configurations and edges on which the checker measured and the numpy
    reference agree, over both worlds."""
    same = total = 0
    for (world, checker), key in ((cloud, ""), (prims, "_primitives")):
        ref = SphereCollisionChecker(robot, spheres, world)
        same += int(np.sum(ref.config_valid(Q) == checker.config_valid(Q)))
        a, b = edges[key]
        same += int(np.sum(ref.edges_valid(a, b) == checker.edges_valid(a, b)))
        total += len(Q) + len(a)
    return {"agreement": same / total, "agreement_cases": total}


def _rate(fn: Any, n: int, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return n / float(np.median(times))


def machine() -> dict[str, Any]:
    """What the rates were measured on: the CPU's model name (``/proc/cpuinfo`` on Linux),
    its widest SIMD extension, the cores, and numba's and llvmlite's versions."""
    import llvmlite
    import numba

    name, flags = "", set[str]()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and not name:
                    name = value.strip()
                elif key.strip() in ("flags", "Features"):  # x86 / ARM
                    flags = set(value.split())
                    break
    except OSError:  # not Linux: the platform's name stands, the SIMD is not known
        pass
    name = name or platform.processor() or platform.machine()
    simd = next((f for f in ("avx512f", "avx2", "avx", "sse4_2", "asimd") if f in flags), "")
    return {
        "cpu": name,
        "simd": simd,
        "cores": os.cpu_count(),
        "numba": numba.__version__,
        "llvmlite": llvmlite.__version__,
    }


def run_collision_benchmark(
    robot: RobotModel,
    spheres: SphereModel,
    cfg: CollisionBenchCfg | None = None,
    progress: Any = None,
) -> dict[str, Any]:
    cfg = cfg or CollisionBenchCfg()
    rng = np.random.default_rng(cfg.seed)
    world_p = PrimitiveWorld(benchmark_workcell(rng))
    t0 = time.perf_counter()
    world_c = CloudWorld(world_p.sample_surface(cfg.cloud_points, rng), voxel=cfg.voxel)
    build_s = time.perf_counter() - t0
    check_p = make_checker(robot, spheres, world_p, backend=cfg.checker)
    check_c = make_checker(robot, spheres, world_c, backend=cfg.checker)
    Q = robot.sample_uniform(rng, cfg.batch)
    check_c.config_valid(Q[:100])  # first calls compile or load the kernels
    check_p.config_valid(Q[:100])
    results: dict[str, Any] = {
        "checker": cfg.checker,
        "machine": machine(),
        "configs_per_s_cloud": _rate(lambda: check_c.config_valid(Q), cfg.batch, cfg.repeats),
        "configs_per_s_primitives": _rate(lambda: check_p.config_valid(Q), cfg.batch, cfg.repeats),
    }
    results.update(_single_call_us(check_c, Q, cfg.single_calls))
    valid_share = float(check_c.config_valid(Q).mean())
    edges: dict[str, tuple[Array, Array]] = {}
    for key, checker in (("", check_c), ("_primitives", check_p)):
        starts = Q[checker.config_valid(Q)][: cfg.edges]
        direction = rng.normal(size=starts.shape)
        ends = starts + direction / np.linalg.norm(direction, axis=1, keepdims=True)
        edges[key] = (starts, ends)
        results[f"edges_per_s{key}"] = _rate(
            lambda c=checker, a=starts, b=ends: c.edges_valid(a, b), len(starts), cfg.repeats
        )
    starts, ends = edges[""]
    results["edge_samples_mean"] = float(check_c.edge_steps(starts, ends).mean() + 1)
    results["edge_valid_share"] = float(check_c.edges_valid(starts, ends).mean())
    results.update(_agreement(robot, spheres, Q, edges, (world_c, check_c), (world_p, check_p)))

    assert isinstance(check_c, SphereCollisionChecker)  # both backends are
    fk_err = 0.0
    for q in Q[:500]:
        ours = check_c.sphere_centers(q[None])[0]
        pinocchio_says = reference_points(robot, q, check_c.sphere_joint, check_c.sphere_local)
        fk_err = max(fk_err, float(np.abs(ours - pinocchio_says).max()))
    results["fk_max_err_m"] = fk_err

    near: list[Array] = []
    while sum(len(n) for n in near) < cfg.mesh_samples:
        cand = robot.sample_uniform(rng, cfg.batch)
        near.append(cand[check_p.world_clearance(cand) < cfg.near_band])
    Qn = np.concatenate(near)[: cfg.mesh_samples]
    # Imported here: PyBullet prints a banner on import, which commands that never use the
    # mesh reference should not show.
    from planning.mesh_reference import MeshReference

    with MeshReference(robot, world_p) as ref:
        iterator = progress(Qn, desc="mesh reference") if progress else Qn
        truth = np.array([ref.collides(q) for q in iterator])
    for key, checker in (("", check_p), ("_cloud", check_c)):
        free = checker.world_clearance(Qn) >= checker.margin
        results[f"mesh_missed{key}"] = int(np.sum(truth & free))
        results[f"mesh_false_alarm_rate{key}"] = float(
            np.sum(~truth & ~free) / max(np.sum(~truth), 1)
        )
    results["mesh_missed"] += results.pop("mesh_missed_cloud")
    results.update(
        mesh_samples=len(Qn),
        mesh_colliding_share=float(truth.mean()),
        near_band_m=cfg.near_band,
        margin_m=check_c.margin,
        voxel_m=cfg.voxel,
        n_spheres=len(spheres),
        n_primitives=len(world_p),
        cloud_points=cfg.cloud_points,
        cloud_build_s=build_s,
        valid_share_uniform=valid_share,
        batch=cfg.batch,
    )
    return results
