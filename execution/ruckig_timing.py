"""Time parameterization with Ruckig, segment by segment, that keeps the checked path.

Steps: check the path (shape, finite, joint limits, every edge valid), shortcut it
(:func:`planning.path_ops.pull_string`), then time it waypoint to waypoint:

- ``exact``: every segment is a phase-synchronized Ruckig move from rest to rest, which is
  the straight joint-space line between the waypoints: the trajectory stays on the checked
  path (to Ruckig's rounding, ~1e-12 rad).
- ``blended``: the corners are first cut with checked chords
  (:func:`planning.path_ops.cut_corners`),
  then the inner waypoints get velocities (:mod:`execution.blend`) and each segment is a
  time-synchronized Ruckig move between them, so the robot does not stop. Blends leave the
  straight edges, so every blended segment is re-checked at the controller rate
  (:mod:`execution.recheck`: samples, the motion between them, the joint limits). A segment
  that fails is slowed (its waypoints' speeds capped at half) up to ``blend_retries``
  times, then falls back to exact (both its waypoints stop); the other waypoints'
  velocities are chosen again and the changed segments re-checked, until every segment
  passes.

Velocity, acceleration and jerk limits hold by Ruckig's construction at every instant; the
position limits hold because exact segments are convex combinations of waypoints inside them
and blended ones are checked. The trajectory is sampled at ``rate_hz`` from t = 0; the last
sample is the first one at or after the end and holds the goal at rest.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import numpy.typing as npt
import ruckig

from execution.blend import choose_velocities
from execution.limits import JointLimits, limits_for
from execution.path_input import as_path, check_path_valid
from execution.recheck import recheck
from execution.ruckig_segments import SegmentChain, SegmentPlanner
from execution.timing_cfg import MAX_SAMPLES, TimingCfg, TimingMode
from execution.trajectory import SegmentInfo, TimedTrajectory, TimingStatus
from gaide_core.errors import TimingError
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.path_ops import cut_corners, pull_string

log = logging.getLogger(__name__)


def _ms(t0: float) -> float:
    return 1e3 * (time.perf_counter() - t0)


class RuckigParameterizer:
    """:class:`~execution.parameterizer.TimeParameterizer` with Ruckig (see module doc)."""

    name = "ruckig"

    def __init__(self, cfg: TimingCfg | None = None) -> None:
        self.cfg = cfg or TimingCfg()

    def limits(self, checker: CollisionChecker) -> JointLimits:
        cfg = self.cfg
        return limits_for(
            checker.robot,
            velocity=cfg.max_velocity,
            acceleration=cfg.max_acceleration,
            jerk=cfg.max_jerk,
            velocity_scale=cfg.velocity_scale,
            acceleration_scale=cfg.acceleration_scale,
            jerk_scale=cfg.jerk_scale,
        )

    def parameterize(self, path: npt.ArrayLike, checker: CollisionChecker) -> TimedTrajectory:
        cfg = self.cfg
        t_start = time.perf_counter()
        limits = self.limits(checker)
        P = as_path(path, limits)
        input_waypoints, input_length = len(P), _length(P)
        check_path_valid(P, checker)
        figures: dict[str, float] = {"ms_check": _ms(t_start)}
        t0 = time.perf_counter()
        if cfg.shortcut:
            P = pull_string(P, checker)
            figures["shortcut_waypoints"] = len(P)
            if cfg.mode is TimingMode.BLENDED:
                P = cut_corners(P, checker)
        figures["ms_shortcut"] = _ms(t0)
        planner = SegmentPlanner(limits)
        t0 = time.perf_counter()
        notes: list[str] = []
        if cfg.mode is TimingMode.EXACT:
            kinds = [("straight", k) for k in range(len(P) - 1)]
            segments = [self._exact(planner, P, k) for k in range(len(P) - 1)]
            figures.update(ms_recheck=0.0, recheck_samples=0, fallbacks=0)
        else:
            kinds, segments = self._blended(planner, P, checker, figures, notes)
        figures["ms_timing"] = _ms(t0) - figures["ms_recheck"]
        t0 = time.perf_counter()
        chain = SegmentChain(segments, limits.dof)
        n = int(np.ceil(chain.duration * cfg.rate_hz - 1e-9))
        if n + 1 > MAX_SAMPLES:  # checked before the samples are allocated
            raise TimingError(
                f"the trajectory lasts {chain.duration:.0f} s: {n + 1:,} samples at "
                f"{cfg.rate_hz:g} Hz, more than {MAX_SAMPLES:,}; raise the velocity, "
                "acceleration or jerk scales (or limits), or lower the rate"
            )
        t = np.arange(n + 1) / cfg.rate_hz
        q, qd, qdd, jerk = chain.evaluate(t)
        figures["ms_sample"] = _ms(t0)
        figures.update(
            input_waypoints=input_waypoints,
            input_length_rad=input_length,
            waypoints=len(P),
            path_length_rad=_length(P),
            ruckig_calls=planner.calls,
            ms_total=_ms(t_start),
        )
        infos = tuple(
            SegmentInfo(
                kind=kind,
                index=index,
                start_s=float(chain.starts[m]),
                duration_s=float(chain.durations[m]),
            )
            for m, (kind, index) in enumerate(kinds)
        )
        return TimedTrajectory(
            t=t,
            q=q,
            qd=qd,
            qdd=qdd,
            jerk=jerk,
            joint_names=limits.names,
            rate_hz=cfg.rate_hz,
            mode=cfg.mode,
            status=TimingStatus.FELL_BACK if notes else TimingStatus.SUCCESS,
            path=P,
            segments=infos,
            limits=limits,
            figures=figures,
            notes=tuple(notes),
            chain=chain,
        )

    @staticmethod
    def _exact(planner: SegmentPlanner, P: Array, k: int) -> ruckig.Trajectory:
        traj = planner.plan_line(P[k], P[k + 1])
        if traj is None:
            raise TimingError(
                f"Ruckig found no rest-to-rest trajectory for edge {k} "
                f"({P[k].tolist()} -> {P[k + 1].tolist()}); check the limits "
                f"{planner.limits.as_dict()}"
            )
        return traj

    def _blended(
        self,
        planner: SegmentPlanner,
        P: Array,
        checker: CollisionChecker,
        figures: dict[str, float],
        notes: list[str],
    ) -> tuple[list[tuple[str, int]], list[ruckig.Trajectory]]:
        """Pass-through blends (:mod:`execution.blend`), re-checked until every one passes."""
        cfg = self.cfg
        K = len(P)
        cap = np.full(K, np.inf)  # largest speed per waypoint (rad/s); 0: it stops
        cap[[0, -1]] = 0.0
        tries = np.zeros(K - 1, np.int64)

        def choose(initial: Array | None) -> Array:
            V, _ = choose_velocities(
                P, planner, cap=cap, levels=cfg.blend_levels, sweeps=cfg.blend_sweeps,
                initial=initial,
            )  # fmt: skip
            return V

        V = choose(None)
        cleared: set[tuple[int, bytes, bytes]] = set()  # segments re-checked clear
        recheck_ms, samples = 0.0, 0
        while True:
            kinds: list[tuple[str, int]] = []
            segments: list[ruckig.Trajectory] = []
            todo: dict[int, ruckig.Trajectory] = {}
            bad: dict[int, str] = {}
            for k in range(K - 1):
                if cap[k] == 0 and cap[k + 1] == 0:  # rest to rest: the checked edge itself
                    kinds.append(("straight", k))
                    segments.append(self._exact(planner, P, k))
                    continue
                traj = planner.plan(P[k], P[k + 1], V[k], V[k + 1])
                if traj is None:
                    bad[k] = "has no Ruckig solution"
                    continue
                kinds.append(("blend", k))
                segments.append(traj)
                if (k, V[k].tobytes(), V[k + 1].tobytes()) not in cleared:
                    todo[k] = traj
            t0 = time.perf_counter()
            verdicts, n = recheck(todo, checker, planner.limits, cfg.dt)
            recheck_ms += _ms(t0)
            samples += n
            for k, why in verdicts.items():
                if why:
                    bad[k] = why
                else:
                    cleared.add((k, V[k].tobytes(), V[k + 1].tobytes()))
            if not bad:
                break
            for k, why in bad.items():
                tries[k] += 1
                ends = [i for i in (k, k + 1) if 0 < i < K - 1]
                if tries[k] > cfg.blend_retries:
                    log.debug("segment %d: the blend %s; exact", k, why)
                    cap[ends] = 0.0
                    notes.append(f"segment {k} (waypoints {k} -> {k + 1}): the blend {why}; exact")
                else:  # a slower blend before giving it up
                    for i in ends:
                        cap[i] = min(cap[i], 0.5 * float(np.linalg.norm(V[i])))
            V = choose(V)
        figures.update(ms_recheck=recheck_ms, recheck_samples=samples, fallbacks=len(notes))
        return kinds, segments


def _length(P: Array) -> float:
    return float(np.sum(np.linalg.norm(np.diff(P, axis=0), axis=1)))


def time_parameterize(
    path: npt.ArrayLike, checker: CollisionChecker, cfg: TimingCfg | None = None
) -> TimedTrajectory:
    """The data flow's ``execution.time_parameterize``: :class:`RuckigParameterizer` with
    ``cfg`` (default: blended at 500 Hz) on ``path`` (K, dof) rad."""
    return RuckigParameterizer(cfg).parameterize(path, checker)
