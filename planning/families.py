"""The paper's six held-out task families, generated from a seed.

The robot stands at the base origin on a 2 cm adapter plate (table top at z = -0.02 m).
Starts and goals come from collision-free IK on end-effector (``tool0``) targets: top-down
poses over the table, in boxes and bins; horizontal poses reaching into shelf levels. Both
ends are valid and at least 5 cm apart at the end effector.

- ``tabletop``: among 4-8 objects on the table.
- ``box``: from inside an open box to the table, or back.
- ``bins``: from one bin to another.
- ``shelf_i``: from the table into a shelf level.
- ``shelf_ii``: from one shelf level to another.
- ``shelf_iii``: deep into a narrow slot (dividers) of a lower, tighter shelf: the hardest.

Seeds: train, validation and test use disjoint ranges (``SEED_RANGES`` of
:mod:`planning.family_names`); a problem's
randomness comes only from (family, seed), so any machine generates the same problem.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from gaide_core.errors import PlanningError
from gaide_core.transforms import from_xyz_rpy
from gaide_core.types import Array
from planning.checker import endpoint_checker, make_checker
from planning.collision import CollisionChecker
from planning.family_names import CATEGORIES, FAMILIES, split_seed
from planning.ik import IKCfg, solve_ik
from planning.kinematics import BatchKinematics
from planning.planner import PlanStatus
from planning.primitives import Box, Cylinder, Primitive, PrimitiveWorld
from planning.problem import Problem, difficulty
from planning.robot_model import RobotModel
from planning.rrtc import CompiledRRTConnect, RRTCCfg
from planning.sphere_model import SphereModel

TABLE_TOP = -0.02  # m
MIN_EE_DISTANCE = 0.05  # m
TIGHT_BELOW = 0.04  # m: a hand nearer than this to an obstacle is in a tight spot
ESCAPE_ITERATIONS = 20_000  # compiled RRT-Connect iterations an end may need to reach home


# -- geometry helpers --------------------------------------------------------------------


def _box(size: npt.ArrayLike, xyz: npt.ArrayLike, yaw: float = 0.0) -> Box:
    return Box(np.asarray(size, float), from_xyz_rpy(xyz, [0.0, 0.0, yaw]))


def _local(origin: npt.ArrayLike, yaw: float, xyz: npt.ArrayLike) -> Array:
    """A point given in a frame at ``origin`` turned by ``yaw`` about z, in the base frame."""
    c, s = np.cos(yaw), np.sin(yaw)
    x, y, z = np.asarray(xyz, float)
    o = np.asarray(origin, float)
    return np.array([o[0] + c * x - s * y, o[1] + s * x + c * y, o[2] + z])


def table(scale: float = 1.0) -> Box:
    return _box([1.6 * scale, 1.6 * scale, 0.04], [0.3 * scale, 0.0, TABLE_TOP - 0.02])


def open_box(
    centre: npt.ArrayLike, yaw: float, inner: tuple[float, float], height: float, wall: float
) -> list[Primitive]:
    """A box open at the top standing on the table: floor and four walls."""
    w, d = inner
    c = np.asarray(centre, float)
    z0 = TABLE_TOP
    parts: list[Primitive] = [
        _box(
            [w + 2 * wall, d + 2 * wall, wall],
            _local(c, yaw, [0, 0, wall / 2]) + np.array([0.0, 0.0, z0]),
            yaw,
        )
    ]
    zc = z0 + wall + height / 2
    for sx in (-1, 1):
        parts.append(
            _box(
                [wall, d + 2 * wall, height],
                _local(c, yaw, [sx * (w + wall) / 2, 0, 0]) + np.array([0.0, 0.0, zc]),
                yaw,
            )
        )
    for sy in (-1, 1):
        parts.append(
            _box(
                [w, wall, height],
                _local(c, yaw, [0, sy * (d + wall) / 2, 0]) + np.array([0.0, 0.0, zc]),
                yaw,
            )
        )
    return parts


@dataclass(frozen=True)
class Shelf:
    front: Array  # (3,) front-centre at table height, base frame
    yaw: float  # local +x points into the shelf (away from the robot)
    width: float
    depth: float
    boards: tuple[float, ...]  # board top heights above the table (m), bottom first
    slots: tuple[float, ...] = ()  # divider y positions (local) on the second level

    def parts(self, board: float = 0.02, wall: float = 0.02) -> list[Primitive]:
        out: list[Primitive] = []
        top = self.boards[-1]
        for h in self.boards:
            out.append(
                _box(
                    [self.depth, self.width, board],
                    _local(self.front, self.yaw, [self.depth / 2, 0, TABLE_TOP + h - board / 2]),
                    self.yaw,
                )
            )
        for sy in (-1, 1):
            out.append(
                _box(
                    [self.depth, wall, top],
                    _local(
                        self.front,
                        self.yaw,
                        [self.depth / 2, sy * (self.width + wall) / 2, TABLE_TOP + top / 2],
                    ),
                    self.yaw,
                )
            )
        out.append(
            _box(
                [wall, self.width + 2 * wall, top],
                _local(self.front, self.yaw, [self.depth + wall / 2, 0, TABLE_TOP + top / 2]),
                self.yaw,
            )
        )
        for y in self.slots:
            lo, hi = self.boards[1], self.boards[2]
            out.append(
                _box(
                    [self.depth, 0.015, hi - lo - board],
                    _local(
                        self.front, self.yaw, [self.depth / 2, y, TABLE_TOP + (lo + hi - board) / 2]
                    ),
                    self.yaw,
                )
            )
        return out


def down_pose(xyz: npt.ArrayLike, yaw: float) -> Array:
    """tool0 pointing straight down at ``xyz`` (base frame), turned by ``yaw``."""
    return from_xyz_rpy(xyz, [np.pi, 0.0, yaw])


def reach_pose(xyz: npt.ArrayLike, heading: float, tilt: float, roll: float) -> Array:
    """tool0 pointing horizontally along ``heading`` (rad about z), tilted by ``tilt`` (rad,
    down positive) and rolled about its own axis by ``roll``."""
    z = np.array([np.cos(heading) * np.cos(tilt), np.sin(heading) * np.cos(tilt), -np.sin(tilt)])
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = Rotation.from_rotvec(z * roll).as_matrix() @ np.stack([x, y, z], axis=1)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, xyz
    return T


# -- generators ------------------------------------------------------------------------

#: The UR5's reach (m, tool0 from the first joint's origin; :func:`reach`): the families'
#: distances are the paper's for this reach.
UR5_REACH = 0.949


def reach(robot: RobotModel, samples: int = 4000) -> float:
    """How far the end effector gets from the first joint's origin (m): the largest distance
    over ``samples`` seeded random configurations (the same number on every machine)."""
    origin = robot.T_world_base[:3, :3] @ robot.model.jointPlacements[1].translation
    origin = origin + robot.T_world_base[:3, 3]
    ee = robot.model.frames[robot.ee_frame]
    Q = robot.sample_uniform(np.random.default_rng(0), samples)
    P = BatchKinematics(robot).points(
        Q, np.array([ee.parentJoint], np.int64), np.asarray(ee.placement.translation)[None]
    )[:, 0]
    return float(np.max(np.linalg.norm(P - origin, axis=1)))


@functools.lru_cache(maxsize=16)
def workspace_scale(robot: RobotModel) -> float:
    """The robot's :func:`reach` over the UR5's, to two decimals (1.0 for the UR5): the
    factor on every family's distances from the base, so each family asks the same of any
    arm."""
    return round(reach(robot) / UR5_REACH, 2)


@dataclass
class _Ctx:
    robot: RobotModel
    checker: CollisionChecker
    rng: np.random.Generator

    prefer: Array | None = None  # pick the IK solution nearest this (None: a random one)
    # Every end must reach this configuration (:func:`_anchor`) with the plain ``planning``
    # checker: see :meth:`escapes`.
    anchor: Array | None = None
    planning: CollisionChecker | None = None

    def ik(self, T: Array) -> Array | None:
        sols = solve_ik(
            self.robot, T, self.rng, cfg=IKCfg(restarts=10, max_solutions=3), checker=self.checker
        )
        if not sols:
            return None
        prefer = self.prefer
        if prefer is None:
            return sols[int(self.rng.integers(len(sols)))]
        # The solution nearest the robot's home posture: a random one can be folded against
        # a joint limit in a pocket of the free space that no motion leaves (measured: such
        # ends made 1% of the category problems unsolvable by any planner).
        return min(sols, key=lambda q: float(np.linalg.norm(q - prefer)))

    def escapes(self, q: Array, start: Array | None = None) -> bool:
        """True if ``q`` reaches the anchor within ESCAPE_ITERATIONS of the compiled
        RRT-Connect (seeded: the same answer on any machine). An IK branch folded against a
        joint limit in a bin or under a shelf can sit in a pocket no motion leaves (measured:
        9 of 30 UR10 category problems before this check).

        A scene where no named configuration is valid has no anchor: there a goal must reach
        its problem's ``start`` instead (a start is taken as it is). Without this, such a
        scene gave `tabletop-2000166-tight2free`, whose ends lie in parts of the free space
        that do not join: no planner solved it (rrtc in three 40 s runs)."""
        if self.planning is None:
            return True
        to = self.anchor if self.anchor is not None else start
        if to is None:
            return True
        planner = CompiledRRTConnect(RRTCCfg(max_iterations=ESCAPE_ITERATIONS, simplify=False))
        found = planner.search(self.planning, q, to, np.random.default_rng(0))
        return found.status is PlanStatus.SUCCESS


# Draws a candidate end-effector pose with the generator it is given (the scene's, or a
# pair's own when one scene serves several start/goal pairs).
Target = Callable[[np.random.Generator], Array]


def _clutter(
    rng: np.random.Generator, n: int, keep_clear: list[Array], scale: float
) -> list[Primitive]:
    """n boxes and cylinders on the table, 0.3-0.75 m from the base (times ``scale``), away
    from given spots."""
    out: list[Primitive] = []
    while len(out) < n:
        r, a = scale * rng.uniform(0.3, 0.75), rng.uniform(-2.4, 2.4)
        xy = np.array([r * np.cos(a), r * np.sin(a)])
        if any(np.linalg.norm(xy - k[:2]) < 0.12 for k in keep_clear):
            continue
        h = rng.uniform(0.06, 0.3)
        if rng.random() < 0.35:
            out.append(
                Cylinder(
                    float(rng.uniform(0.025, 0.06)),
                    h,
                    from_xyz_rpy([*xy, TABLE_TOP + h / 2], [0, 0, 0]),
                )
            )
        else:
            out.append(
                _box(
                    rng.uniform([0.04, 0.04, h], [0.15, 0.15, h]),
                    [*xy, TABLE_TOP + h / 2],
                    rng.uniform(-np.pi, np.pi),
                )
            )
    return out


def _table_target(scale: float) -> Target:
    def draw(rng: np.random.Generator) -> Array:
        r, a = scale * rng.uniform(0.35, 0.7), rng.uniform(-2.2, 2.2)
        return down_pose(
            [r * np.cos(a), r * np.sin(a), TABLE_TOP + rng.uniform(0.06, 0.22)],
            rng.uniform(-np.pi, np.pi),
        )

    return draw


def _in_container(
    centre: Array,
    yaw: float,
    inner: tuple[float, float],
    floor: float,
    height: float,
) -> Target:
    def draw(rng: np.random.Generator) -> Array:
        u = rng.uniform(-0.5, 0.5, 2) * (np.asarray(inner) - 0.12).clip(0.0)
        z = TABLE_TOP + floor + rng.uniform(0.07, max(0.08, height * 0.6))
        return down_pose(
            _local(centre, yaw, [u[0], u[1], 0.0]) + np.array([0.0, 0.0, z]),
            yaw + rng.choice([0.0, np.pi / 2]),
        )

    return draw


def _in_shelf(
    shelf: Shelf,
    level: int,
    depth: tuple[float, float],
    y_range: tuple[float, float] | None = None,
) -> Target:
    lo, hi = shelf.boards[level], shelf.boards[level + 1]

    def draw(rng: np.random.Generator) -> Array:
        half = shelf.width / 2 - 0.12
        y = rng.uniform(*(y_range or (-half, half)))
        x = shelf.depth * rng.uniform(*depth)
        z = TABLE_TOP + lo + (hi - lo) * rng.uniform(0.4, 0.6)
        p = _local(shelf.front, shelf.yaw, [x, y, 0.0]) + np.array([0.0, 0.0, z])
        return reach_pose(
            p,
            shelf.yaw + rng.uniform(-0.15, 0.15),
            rng.uniform(-0.1, 0.2),
            rng.uniform(-np.pi, np.pi),
        )

    return draw


def _shelf(
    rng: np.random.Generator,
    *,
    spacing: tuple[float, float],
    levels: int,
    width: tuple[float, float],
    depth: float,
    dist: tuple[float, float],
    scale: float,
    slots: bool = False,
) -> Shelf:
    heading = rng.uniform(-0.6, 0.6)
    d = scale * rng.uniform(*dist)
    front = np.array([d * np.cos(heading), d * np.sin(heading), 0.0])
    s = rng.uniform(*spacing)
    first = rng.uniform(0.0, 0.12)
    boards = tuple(first + s * k for k in range(levels + 1))
    w = rng.uniform(*width)
    dividers: tuple[float, ...] = ()
    if slots:
        slot = rng.uniform(0.3, 0.36)
        dividers = (-slot / 2, slot / 2)
    return Shelf(front, heading, w, depth, boards, dividers)


def _two_level_shelf(rng: np.random.Generator, scale: float, slots: bool = False) -> Shelf:
    """The shelves' shelf: two levels 28-34 cm apart, 60-80 cm wide, 32 cm deep, its front
    45-55 cm from the base (times ``scale``)."""
    return _shelf(
        rng,
        spacing=(0.28, 0.34),
        levels=2,
        width=(0.6, 0.8),
        depth=0.32,
        dist=(0.45, 0.55),
        scale=scale,
        slots=slots,
    )


def _scene(
    family: str, rng: np.random.Generator, scale: float = 1.0
) -> tuple[list[Primitive], Target, Target]:
    """Obstacles (table first) and two target samplers (start, goal) for one family.
    Distances from the base are multiplied by ``scale`` (:func:`workspace_scale`); the
    objects keep their sizes (a gripper is as big on any arm)."""
    s = scale
    prims: list[Primitive] = [table(s)]
    if family == "tabletop":
        prims += _clutter(rng, int(rng.integers(4, 9)), [], s)
        return prims, _table_target(s), _table_target(s)
    if family == "box":
        r, a = s * rng.uniform(0.45, 0.6), rng.uniform(-1.2, 1.2)
        centre = np.array([r * np.cos(a), r * np.sin(a), 0.0])
        inner = (float(rng.uniform(0.28, 0.4)), float(rng.uniform(0.28, 0.4)))
        height, yaw = float(rng.uniform(0.12, 0.22)), float(a + rng.uniform(-0.3, 0.3))
        prims += open_box(centre, yaw, inner, height, 0.015)
        prims += _clutter(rng, int(rng.integers(1, 4)), [centre], s)
        inside = _in_container(centre, yaw, inner, 0.015, height)
        outside = _table_target(s)
        return (prims, inside, outside) if rng.random() < 0.5 else (prims, outside, inside)
    if family == "bins":
        n = int(rng.integers(2, 4))
        angles = np.sort(rng.choice(np.linspace(-1.6, 1.6, 7), n, replace=False))
        bins = []
        for a in angles:
            r = s * rng.uniform(0.45, 0.6)
            centre = np.array([r * np.cos(a), r * np.sin(a), 0.0])
            inner = (float(rng.uniform(0.22, 0.3)), float(rng.uniform(0.22, 0.3)))
            height = float(rng.uniform(0.08, 0.15))
            prims += open_box(centre, float(a), inner, height, 0.012)
            bins.append(_in_container(centre, float(a), inner, 0.012, height))
        i, j = rng.choice(n, 2, replace=False)
        return prims, bins[i], bins[j]
    if family in ("shelf_i", "shelf_ii"):
        shelf = _two_level_shelf(rng, s)
        prims += shelf.parts()
        if family == "shelf_i":
            prims += _clutter(rng, int(rng.integers(0, 3)), [shelf.front], s)
            level = _in_shelf(shelf, int(rng.integers(0, 2)), (0.15, 0.45))
            return (
                (prims, _table_target(s), level)
                if rng.random() < 0.5
                else (prims, level, _table_target(s))
            )
        low, high = _in_shelf(shelf, 0, (0.15, 0.45)), _in_shelf(shelf, 1, (0.15, 0.45))
        return (prims, low, high) if rng.random() < 0.5 else (prims, high, low)
    if family == "shelf_iii":
        shelf = _two_level_shelf(rng, s, slots=True)
        prims += shelf.parts()
        slot_half = shelf.slots[1] - 0.1
        deep = _in_shelf(shelf, 1, (0.3, 0.45), (-slot_half, slot_half))
        other = _in_shelf(shelf, 0, (0.15, 0.4)) if rng.random() < 0.6 else _table_target(s)
        return (prims, other, deep) if rng.random() < 0.5 else (prims, deep, other)
    raise PlanningError(f"unknown family '{family}'; valid: {list(FAMILIES)}")


def generate_problem(
    family: str,
    seed: int,
    robot: RobotModel,
    spheres: SphereModel,
    *,
    category: str | None = None,
    scene_attempts: int = 20,
    target_attempts: int = 12,
) -> Problem:
    """The problem of ``family`` for ``seed``: same inputs, same problem, on any machine.

    Without ``category``, the family's own start and goal targets decide how tight the ends
    are (the legacy test split). With one of :data:`CATEGORIES`, each end is made tight (the
    family's targets: in the box, bin or shelf, among the clutter) or free (open space above
    the table), checked on the hand's clearance. The scene comes from (family, seed) alone
    and each category's ends from a generator of their own, so the four categories of one
    seed share a scene (the training data reuses it for four start/goal pairs)."""
    if family not in FAMILIES:
        raise PlanningError(f"unknown family '{family}'; valid: {list(FAMILIES)}")
    if category is not None:
        return _in_category(family, seed, robot, spheres, category, scene_attempts)
    rng = np.random.default_rng([FAMILIES.index(family), seed])
    for _ in range(scene_attempts):
        prims, start_target, goal_target = _scene(family, rng, workspace_scale(robot))
        world = PrimitiveWorld(prims)
        # Endpoints keep ENDPOINT_SLACK beyond the margin: certified motions can reach them.
        plain = make_checker(robot, spheres, world)
        ctx = _Ctx(robot, endpoint_checker(plain), rng, None, _anchor(robot, plain), plain)
        start = _solve(ctx, start_target, target_attempts)
        if start is None:
            continue
        p_start = robot.frame_pose(start)[:3, 3]
        for _ in range(target_attempts):
            T_goal = goal_target(rng)
            if np.linalg.norm(T_goal[:3, 3] - p_start) < MIN_EE_DISTANCE:
                continue
            goal = ctx.ik(T_goal)
            if goal is None or not ctx.escapes(goal, start):
                continue
            clear = ctx.checker.world_clearance(np.stack([start, goal]), links=_hand_links(robot))
            return Problem(
                name=f"{family}-{seed}",
                family=family,
                seed=seed,
                world=world,
                start=start,
                goal=goal,
                difficulty=difficulty(float(clear[0]), float(clear[1]), TIGHT_BELOW),
            )
    raise PlanningError(f"{family} seed {seed}: no valid start and goal in {scene_attempts} scenes")


def _free_target(scale: float) -> Target:
    """Open space: a top-down pose 25-60 cm above the table, 30-65 cm from the base (both
    times ``scale``)."""

    def draw(rng: np.random.Generator) -> Array:
        r, a = scale * rng.uniform(0.3, 0.65), rng.uniform(-np.pi, np.pi)
        z = TABLE_TOP + scale * rng.uniform(0.25, 0.6)
        return down_pose([r * np.cos(a), r * np.sin(a), z], rng.uniform(-np.pi, np.pi))

    return draw


def _in_category(
    family: str,
    seed: int,
    robot: RobotModel,
    spheres: SphereModel,
    category: str,
    scene_attempts: int,
    attempts: int = 40,
) -> Problem:
    if category not in CATEGORIES:
        raise PlanningError(f"unknown category '{category}'; valid: {list(CATEGORIES)}")
    want = category.split("2")
    hand = _hand_links(robot)
    scene_rng = np.random.default_rng([FAMILIES.index(family), seed])
    for attempt in range(scene_attempts):
        prims, target_a, target_b = _scene(family, scene_rng, workspace_scale(robot))
        world = PrimitiveWorld(prims)
        rng = np.random.default_rng(
            [FAMILIES.index(family), seed, attempt, 1 + CATEGORIES.index(category)]
        )
        plain = make_checker(robot, spheres, world)
        ctx = _Ctx(robot, endpoint_checker(plain), rng, _home(robot), _anchor(robot, plain), plain)
        targets = {"tight": (target_a, target_b), "free": (_free_target(workspace_scale(robot)),)}
        start = _end_of_kind(ctx, targets[want[0]], want[0] == "tight", hand, attempts)
        if start is None:
            continue
        goal = _end_of_kind(ctx, targets[want[1]], want[1] == "tight", hand, attempts, start)
        if goal is None:
            continue
        return Problem(
            name=f"{family}-{seed}-{category}",
            family=family,
            seed=seed,
            world=world,
            start=start,
            goal=goal,
            difficulty=category,
        )
    raise PlanningError(
        f"{family} seed {seed}: no {category} start and goal in {scene_attempts} scenes"
    )


def _end_of_kind(
    ctx: _Ctx,
    targets: tuple[Target, ...],
    tight: bool,
    hand: tuple[str, ...],
    attempts: int,
    start: Array | None = None,
) -> Array | None:
    """A collision-free IK solution for one of ``targets`` whose hand clearance is under
    TIGHT_BELOW (``tight``) or not, that leaves for home (:meth:`_Ctx.escapes`), and, for a
    goal (``start`` given), whose end effector is MIN_EE_DISTANCE from the start's; None
    after ``attempts`` targets."""
    far_from = None if start is None else ctx.robot.frame_pose(start)[:3, 3]
    for _ in range(attempts):
        T = targets[int(ctx.rng.integers(len(targets)))](ctx.rng)
        if far_from is not None and np.linalg.norm(T[:3, 3] - far_from) < MIN_EE_DISTANCE:
            continue
        q = ctx.ik(T)
        if q is None:
            continue
        clear = float(ctx.checker.world_clearance(q[None], links=hand)[0])
        if (clear < TIGHT_BELOW) == tight and ctx.escapes(q, start):
            return q
    return None


def _home(robot: RobotModel) -> Array:
    """The robot's ``home`` configuration, or the middle of its joint ranges."""
    named = robot.config.named_configurations
    return named["home"].copy() if "home" in named else (robot.lower + robot.upper) / 2


def _anchor(robot: RobotModel, checker: CollisionChecker) -> Array | None:
    """What every end must reach (:meth:`_Ctx.escapes`): ``home``, or the first other named
    configuration valid in this scene (a shelf can stand where home's forearm is); None
    when none is."""
    named = robot.config.named_configurations
    candidates = [_home(robot), *(q for name, q in named.items() if name != "home")]
    return next((q for q in candidates if checker.config_valid_one(q)), None)


def _hand_links(robot: RobotModel) -> tuple[str, ...]:
    """The links of the last three joints (the wrist and what it carries): tightness is about
    the hand's surroundings, not the shoulder that always sits near the table."""
    last = set(range(robot.dof - 2, robot.dof + 1))
    return tuple(
        n for n, link in robot.links.items() if link.joint_id in last and n in robot.link_meshes
    )


def _solve(ctx: _Ctx, target: Target, attempts: int) -> Array | None:
    for _ in range(attempts):
        q = ctx.ik(target(ctx.rng))
        if q is not None and ctx.escapes(q):
            return q
    return None


def family_problems(
    family: str,
    robot: RobotModel,
    spheres: SphereModel,
    *,
    split: str = "test",
    count: int = 10,
    first: int = 0,
) -> list[Problem]:
    return [
        generate_problem(family, split_seed(split, first + i), robot, spheres) for i in range(count)
    ]
