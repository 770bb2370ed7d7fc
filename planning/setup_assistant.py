"""``gaide robot setup``: a complete robot config from a URDF alone, as MoveIt's setup
assistant makes one.

From the URDF's tree it picks the planning chain (``--base-link`` to ``--tip-link``; by
default from the root down to where the arm branches into a gripper's fingers or ends),
locks every other movable joint (``--lock J=V`` values, else the value nearest 0 inside the
joint's limits), takes position and velocity limits from the URDF, fills acceleration and
jerk with documented defaults, picks the end-effector frame (a tool/TCP frame fixed to the
tip), spherizes the collision meshes, and computes the self-collision matrix: link pairs
adjacent in the tree, in collision at ``home``, in collision in nearly every random
configuration, or never in collision over many random configurations are not checked. The
matrix is computed on the sphere model the planners check, so a pair the spheres make
collide by construction (neighbours-but-one whose spheres overlap) is found too.

The written config (``robot.yaml``) and sphere file (``<name>_spheres.yaml``) appear
together or not at all.
"""

from __future__ import annotations

import json
import math
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaide_core.atomic import write_files_atomic
from gaide_core.errors import ConfigError, RobotModelError
from gaide_core.types import Array, IntArray
from planning.collision import SphereCollisionChecker
from planning.robot_config import RobotConfig, example_robot_data_share, resolve_uri
from planning.robot_model import RobotModel, read_xml
from planning.sphere_model import SphereModel
from planning.spherize import SpherizeCfg, generate_spheres

#: rad/s^2 (m/s^2 for prismatic joints): URDFs carry no acceleration limits. Below every
#: listed arm's datasheet (Panda's smallest is 7.5 rad/s^2): edit them to your controller's.
DEFAULT_ACCELERATION = 5.0
#: rad/s^3 (m/s^3): ten times the acceleration, as the UR5 config.
DEFAULT_JERK = 50.0
#: rad/s (m/s) for a joint whose URDF velocity limit is missing or zero.
DEFAULT_VELOCITY = 1.0
#: MoveIt's default sampling density for the self-collision matrix.
COLLISION_SAMPLES = 10_000
#: A pair in collision in at least this share of the samples is "always" in collision.
ALWAYS_SHARE = 0.95
#: Link names that mark a tool frame, in order of preference (substring match).
TOOL_FRAME_HINTS = ("tcp", "tool0", "eef", "ee_link", "tool", "flange")

MOVABLE = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    kind: str  # URDF joint type
    parent: str
    child: str
    lower: float  # position limits (0 when the URDF gives none)
    upper: float


@dataclass(frozen=True)
class UrdfTree:
    """The links and joints of a URDF, checked to form one tree."""

    path: Path
    links: tuple[str, ...]
    joints: tuple[UrdfJoint, ...]
    root: str
    collision_meshes: tuple[tuple[str, str], ...]  # (link, mesh filename as written)

    def children(self, link: str) -> list[UrdfJoint]:
        return [j for j in self.joints if j.parent == link]

    def parent_joint(self, link: str) -> UrdfJoint | None:
        return next((j for j in self.joints if j.child == link), None)

    def joint(self, name: str) -> UrdfJoint:
        for j in self.joints:
            if j.name == name:
                return j
        raise RobotModelError(
            f"URDF {self.path} has no joint '{name}'; its joints: {[j.name for j in self.joints]}"
        )

    def check_link(self, name: str, what: str) -> str:
        if name not in self.links:
            raise RobotModelError(
                f"{what}: URDF {self.path} has no link '{name}'; its links: {list(self.links)}"
            )
        return name

    def moves_below(self, joint: UrdfJoint) -> bool:
        """True if ``joint`` or any joint below it is movable."""
        return joint.kind in MOVABLE or any(self.moves_below(j) for j in self.children(joint.child))

    def chain(self, base: str, tip: str) -> list[UrdfJoint]:
        """The joints from ``base`` down to ``tip``; RobotModelError if tip is not below base."""
        out: list[UrdfJoint] = []
        link = tip
        while link != base:
            joint = self.parent_joint(link)
            if joint is None:
                raise RobotModelError(
                    f"--tip-link {tip} is not below --base-link {base} in URDF {self.path}"
                )
            out.append(joint)
            link = joint.parent
        return out[::-1]

    def fixed_descendants(self, link: str) -> list[tuple[str, int]]:
        """Links fixed to ``link`` (through fixed joints only), with their depth."""
        out: list[tuple[str, int]] = []
        stack = [(link, 0)]
        while stack:
            here, depth = stack.pop()
            for j in self.children(here):
                if j.kind == "fixed":
                    out.append((j.child, depth + 1))
                    stack.append((j.child, depth + 1))
        return out


def read_urdf_tree(urdf: Path) -> UrdfTree:
    """The URDF's kinematic tree; RobotModelError for what a planning chain cannot be: a
    floating or planar joint, a closed chain (a link with two parents), several roots."""
    root_el = read_xml(urdf, "URDF")
    if root_el.tag != "robot":
        raise RobotModelError(f"{urdf} is not a URDF: its root element is <{root_el.tag}>")
    links = tuple(el.attrib.get("name", "") for el in root_el.findall("link"))
    joints: list[UrdfJoint] = []
    parent_of: dict[str, str] = {}
    for el in root_el.findall("joint"):
        name, kind = el.attrib.get("name", "?"), el.attrib.get("type", "?")
        parent_el, child_el = el.find("parent"), el.find("child")
        if parent_el is None or child_el is None:
            raise RobotModelError(f"URDF {urdf}: joint '{name}' lacks <parent> or <child>")
        parent, child = parent_el.attrib.get("link", ""), child_el.attrib.get("link", "")
        if kind in ("floating", "planar"):
            raise RobotModelError(
                f"URDF {urdf}: joint '{name}' is {kind} (a floating base); a planning chain "
                "needs a fixed base: remove it or make it a fixed joint"
            )
        if kind not in (*MOVABLE, "fixed"):
            raise RobotModelError(
                f"URDF {urdf}: joint '{name}' has type '{kind}'; valid: revolute, continuous, "
                "prismatic, fixed"
            )
        if child in parent_of:
            raise RobotModelError(
                f"URDF {urdf} has a closed chain: link '{child}' is the child of joints "
                f"'{parent_of[child]}' and '{name}'; only tree-shaped URDFs can be planned for"
            )
        for link in (parent, child):
            if link not in links:
                raise RobotModelError(f"URDF {urdf}: joint '{name}' names unknown link '{link}'")
        parent_of[child] = name
        limit = el.find("limit")
        if limit is None and kind in ("revolute", "prismatic"):
            raise RobotModelError(
                f"URDF {urdf}: joint '{name}' is {kind} without a <limit> element; URDF asks "
                "one of every revolute and prismatic joint (lower, upper, velocity, effort)"
            )
        try:
            lower = float(limit.attrib.get("lower", 0.0)) if limit is not None else 0.0
            upper = float(limit.attrib.get("upper", 0.0)) if limit is not None else 0.0
        except ValueError as err:
            raise RobotModelError(
                f"URDF {urdf}: joint '{name}' has a <limit> that is not numbers ({err})"
            ) from err
        joints.append(UrdfJoint(name, kind, parent, child, lower, upper))
    roots = [link for link in links if link not in parent_of]
    if len(roots) != 1:
        raise RobotModelError(
            f"URDF {urdf} has {len(roots)} root links {roots}; a robot has exactly one "
            "(a closed chain has none)"
        )
    meshes = tuple(
        (link.attrib.get("name", ""), mesh.attrib.get("filename", ""))
        for link in root_el.findall("link")
        for mesh in link.findall("collision/geometry/mesh")
    )
    return UrdfTree(urdf, links, tuple(joints), roots[0], meshes)


def check_collision_meshes(tree: UrdfTree, package_dirs: tuple[Path, ...]) -> None:
    """RobotModelError naming the first collision mesh that cannot be found."""
    for link, uri in tree.collision_meshes:
        uri = uri.removeprefix("file://")
        try:
            path = resolve_uri(uri, tree.path.parent, package_dirs)
        except ConfigError as err:
            raise RobotModelError(
                f"URDF {tree.path}: link '{link}' collision mesh {uri}: {err}; add the "
                "package's parent folder with --package-dir"
            ) from err
        if not path.is_file():
            raise RobotModelError(
                f"URDF {tree.path}: link '{link}' collision mesh {uri} is missing ({path})"
            )


def default_tip(tree: UrdfTree, base: str) -> str:
    """Down from ``base`` while exactly one branch still moves: the link where the arm ends
    or splits into a gripper's fingers."""
    link = base
    while True:
        moving = [j for j in tree.children(link) if tree.moves_below(j)]
        if len(moving) != 1:
            return link
        link = moving[0].child


def tool_frame(tree: UrdfTree, tip: str) -> str:
    """A tool frame fixed to ``tip`` (TCP, tool0, eef, ...; else the deepest fixed link),
    or ``tip`` itself."""
    fixed = tree.fixed_descendants(tip)
    for hint in TOOL_FRAME_HINTS:
        named = [(name, depth) for name, depth in fixed if hint in name.lower()]
        if named:
            return max(named, key=lambda nd: nd[1])[0]
    return max(fixed, key=lambda nd: nd[1])[0] if fixed else tip


@dataclass
class SetupResult:
    config_path: Path
    spheres_path: Path
    robot: RobotModel
    spheres: SphereModel
    locked: dict[str, float]
    disabled: dict[tuple[str, str], str]  # link pair -> reason
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True, kw_only=True)
class SetupCfg:
    srdf: Path | None = None
    base_link: str | None = None
    tip_link: str | None = None
    locks: dict[str, float] = field(default_factory=dict)
    named: dict[str, tuple[float, ...]] = field(default_factory=dict)  # --named, rad or m
    package_dirs: tuple[Path, ...] = ()
    samples: int = COLLISION_SAMPLES
    max_spheres: int = 60
    seed: int = 0


def setup_robot(urdf: Path, output: Path, cfg: SetupCfg | None = None) -> SetupResult:
    """Write a robot config for ``urdf`` to ``output`` and its spheres beside it."""
    cfg = cfg or SetupCfg()
    urdf = urdf.resolve()
    tree = read_urdf_tree(urdf)
    share = example_robot_data_share()
    package_dirs = tuple(p.resolve() for p in cfg.package_dirs) + ((share,) if share else ())
    check_collision_meshes(tree, package_dirs)
    srdf = read_xml(cfg.srdf.resolve(), "SRDF") if cfg.srdf else None
    base = tree.check_link(cfg.base_link, "--base-link") if cfg.base_link else tree.root
    tip = tree.check_link(cfg.tip_link, "--tip-link") if cfg.tip_link else default_tip(tree, base)
    chain = {j.name for j in tree.chain(base, tip) if j.kind in MOVABLE}
    locked = _locked_joints(tree, chain, cfg.locks)
    if not chain - set(locked):
        raise RobotModelError(
            f"no joint is left to plan between {base} and {tip}: give --base-link/--tip-link "
            "around the arm's joints"
        )
    notes: list[str] = []
    base_config = RobotConfig(
        urdf=urdf,
        package_dirs=package_dirs,
        srdf=cfg.srdf.resolve() if cfg.srdf else None,
        end_effector=tool_frame(tree, tip),
        locked_joints=locked,
    )
    probe = RobotModel(base_config)
    velocity = np.asarray(probe.model.velocityLimit, float)
    if np.any(velocity <= 0):
        missing = [n for n, v in zip(probe.joint_names, velocity, strict=True) if v <= 0]
        notes.append(f"no velocity limit in the URDF for {missing}: {DEFAULT_VELOCITY} used")
        velocity = np.where(velocity > 0, velocity, DEFAULT_VELOCITY)
    bolted = tuple(
        name
        for name, link in probe.links.items()
        if link.joint_id == 0 and name in probe.link_meshes
    )
    config = base_config.replace(
        velocity_limits=velocity,
        acceleration_limits=np.full(probe.dof, DEFAULT_ACCELERATION),
        jerk_limits=np.full(probe.dof, DEFAULT_JERK),
        world_ignored_links=bolted,
    )
    robot = RobotModel(config)
    spheres = generate_spheres(robot, SpherizeCfg(max_spheres=cfg.max_spheres, seed=cfg.seed))
    given = {k: robot.check_configuration(v, f"--named {k}") for k, v in cfg.named.items()}
    named, home_from = _named_configurations(robot, srdf, given)
    if home_from == "limits":
        notes.append(
            "home is the middle of the joint limits: give --named home=... (your robot's home "
            "posture) so that IK keeps to its branch"
        )
    disabled = collision_matrix(robot, spheres, named["home"], cfg.samples, cfg.seed)
    config = config.replace(
        named_configurations=named,
        ignored_link_pairs=tuple(sorted(disabled)),
    )
    robot = RobotModel(config)
    output = output.resolve()
    spheres_path = output.with_name(f"{output.stem}_spheres.yaml")
    text = config_yaml(config, robot, spheres_path.name, output.parent, disabled)
    write_files_atomic(
        [(spheres_path, spheres.to_yaml().encode()), (output, text.encode())], RobotModelError
    )
    return SetupResult(output, spheres_path, robot, spheres, locked, disabled, notes)


def _locked_joints(tree: UrdfTree, chain: set[str], locks: dict[str, float]) -> dict[str, float]:
    """Every movable joint off the chain (at its --lock value, else the value nearest 0 in
    its limits) and every --lock joint on it."""
    for name in locks:
        joint = tree.joint(name)
        if joint.kind not in MOVABLE:
            raise RobotModelError(f"--lock {name}: joint '{name}' is {joint.kind}, not movable")
    out: dict[str, float] = {}
    for joint in tree.joints:
        if joint.kind not in MOVABLE:
            continue
        if joint.name in locks:
            out[joint.name] = float(locks[joint.name])
        elif joint.name not in chain:
            out[joint.name] = float(np.clip(0.0, joint.lower, joint.upper))
    return out


def _named_configurations(
    robot: RobotModel, srdf: ET.Element | None, given: dict[str, Array]
) -> tuple[dict[str, Array], str]:
    """The SRDF's group states that set every planning joint, then ``given`` (--named), and
    ``home``: given, else the SRDF's home, ready or default state, else the middle of the
    limits (0 where the range holds it near the middle). Also says where home came from."""
    named: dict[str, Array] = {}
    if srdf is not None:
        for state in srdf.iter("group_state"):
            values = {}
            for el in state.findall("joint"):
                name, value = el.attrib.get("name", ""), el.attrib.get("value", "nan")
                try:
                    values[name] = float(value)
                except ValueError as err:
                    raise RobotModelError(
                        f"SRDF group_state '{state.attrib.get('name', '?')}': joint '{name}' "
                        f"has value {value!r}, not a number (rad or m)"
                    ) from err
            if all(n in values for n in robot.joint_names):
                q = np.array([values[n] for n in robot.joint_names])
                if np.all(np.isfinite(q)) and robot.within_limits(q[None])[0]:
                    named[state.attrib.get("name", f"state{len(named)}")] = q
    named.update(given)
    home_from = "given" if "home" in given else "srdf"
    if "home" not in named:
        alias = next((n for n in ("ready", "default") if n in named), None)
        if alias is not None:
            named["home"] = named[alias].copy()
        else:
            middle = (robot.lower + robot.upper) / 2
            zero_inside = (robot.lower <= 0) & (robot.upper >= 0)
            named["home"] = np.where(zero_inside & (np.abs(middle) < 0.5), 0.0, middle)
            home_from = "limits"
    return {"home": named.pop("home"), **named}, home_from


def collision_matrix(
    robot: RobotModel, spheres: SphereModel, home: Array, samples: int, seed: int
) -> dict[tuple[str, str], str]:
    """Link pairs not to check, with the reason: ``default`` (in collision at home),
    ``always`` (in collision in >= ALWAYS_SHARE of ``samples`` random configurations),
    ``never`` (in none of them). Adjacent links are never checked anyway (see
    :meth:`RobotModel.disabled_link_pairs`); SRDF pairs are kept out of the list."""
    checker = SphereCollisionChecker(robot, spheres)
    pairs = checker.pairs
    if len(pairs) == 0:
        return {}
    links = spheres.links

    def link_pair(i: int, j: int) -> tuple[str, str]:
        a, b = sorted((links[i], links[j]))
        return a, b

    index = {p: k for k, p in enumerate(sorted({link_pair(i, j) for i, j in pairs}))}
    pair_of = np.array([index[link_pair(i, j)] for i, j in pairs], np.int64)
    rng = np.random.default_rng(seed)
    hits = np.zeros(len(index), np.int64)
    for start in range(0, samples, 1000):
        Q = robot.sample_uniform(rng, min(1000, samples - start))
        hits += np.count_nonzero(_pair_contacts(checker, Q, pair_of, len(index)), axis=0)
    at_home = _pair_contacts(checker, home[None], pair_of, len(index))[0]
    out: dict[tuple[str, str], str] = {}
    for pair, k in index.items():
        if at_home[k]:
            out[pair] = "default"
        elif hits[k] >= ALWAYS_SHARE * samples:
            out[pair] = "always"
        elif hits[k] == 0:
            out[pair] = "never"
    return out


def _pair_contacts(
    checker: SphereCollisionChecker, Q: Array, pair_of: IntArray, n_pairs: int
) -> Array:
    """(B, n_pairs) True where a link pair's spheres overlap at configuration Q[b]."""
    centers = checker.sphere_centers(Q)
    i, j = checker.pairs[:, 0], checker.pairs[:, 1]
    d2 = np.sum((centers[:, i] - centers[:, j]) ** 2, axis=-1)
    overlap = d2 < checker.pair_reach[None, :]
    out = np.zeros((len(Q), n_pairs), bool)
    for k in range(n_pairs):
        out[:, k] = np.any(overlap[:, pair_of == k], axis=1)
    return out


def _uri(path: Path, folder: Path) -> str:
    """``package://example-robot-data/...`` for the wheel's files, else a path relative to
    the config's folder (so the config moves with its robot)."""
    share = example_robot_data_share()
    if share is not None and path.is_relative_to(share):
        return "package://" + path.relative_to(share).as_posix()
    return Path(os.path.relpath(path, folder)).as_posix()


def name(text: str) -> str:
    """A YAML scalar for a link or joint name: plain when safe, else a JSON string."""
    return text if re.fullmatch(r"[A-Za-z_][\w.\-]*", text) else json.dumps(text)


def _flow(values: Array | list[float]) -> str:
    return "[" + ", ".join(_num(v) for v in values) + "]"


def _num(v: float) -> str:
    return repr(round(float(v), 6)) if math.isfinite(v) else str(v)


def config_yaml(
    config: RobotConfig,
    robot: RobotModel,
    spheres_name: str,
    folder: Path,
    disabled: dict[tuple[str, str], str],
) -> str:
    """The robot config as commented YAML (the loader's keys, :mod:`planning.robot_config`)."""
    lines = [
        f"# Made by `gaide robot setup` from {config.urdf.name}.",
        f"# Planning joints ({robot.dof}): {', '.join(robot.joint_names)}.",
        f"urdf: {_uri(config.urdf, folder)}",
    ]
    if config.srdf is not None:
        lines.append(f"srdf: {_uri(config.srdf, folder)}")
    extra = [p for p in config.package_dirs if p != example_robot_data_share()]
    if extra:
        lines.append("package_dirs: [" + ", ".join(_uri(p, folder) for p in extra) + "]")
    lines += [
        f"spheres: {spheres_name}",
        f"end_effector: {name(config.end_effector)}",
        "base_pose: {xyz: [0.0, 0.0, 0.0], rpy: [0.0, 0.0, 0.0]}",
    ]
    if config.locked_joints:
        lines.append("# Held at these values (rad or m), left out of planning:")
        lines.append(
            "locked_joints: {"
            + ", ".join(f"{name(k)}: {_num(v)}" for k, v in config.locked_joints.items())
            + "}"
        )
    lines += [
        "# From the URDF:",
        "joint_limits:",
        f"  lower: {_flow(robot.lower)}",
        f"  upper: {_flow(robot.upper)}",
        f"velocity_limits: {_flow(robot.velocity_limits)}",
        f"# Defaults ({DEFAULT_ACCELERATION} rad/s^2, {DEFAULT_JERK} rad/s^3): set your "
        "controller's values.",
        f"acceleration_limits: {_flow(robot.acceleration_limits)}",
        f"jerk_limits: {_flow(robot.jerk_limits)}",
        f"collision_margin: {config.collision_margin}  # m",
        f"edge_resolution: {config.edge_resolution}  # m",
        "# Bolted to the mount: checked against the arm only.",
        "world_ignored_links: [" + ", ".join(name(n) for n in config.world_ignored_links) + "]",
        "# Self-collision matrix (MoveIt setup assistant's method on the sphere model): pairs",
        "# in collision at home (default), in nearly every random configuration (always) or",
        "# in none of them (never) are not checked; adjacent links never are.",
    ]
    if disabled:
        lines.append("ignored_link_pairs:")
        lines += [
            f"  - [{name(a)}, {name(b)}]  # {why}" for (a, b), why in sorted(disabled.items())
        ]
    else:
        lines.append("ignored_link_pairs: []")
    lines.append("named_configurations:")
    lines += [f"  {name(k)}: {_flow(v)}" for k, v in config.named_configurations.items()]
    return "\n".join(lines) + "\n"
