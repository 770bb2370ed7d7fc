"""Flange poses (``T_base_flange``) or joint vectors, one per calibration image, from files:
YAML/JSON, CSV, or a folder with one file per image. Units: metres and radians. Everything a
user can get wrong raises ``CalibrationError`` naming the file, the problem and what would be
valid.
"""

from __future__ import annotations

import csv
import logging
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any

import numpy as np

from calibration.fixed import pose_from_dict
from calibration.inputs import IMAGE_SUFFIXES, natural_key, numbers
from gaide_core.errors import CalibrationError
from gaide_core.text_io import load_json, one_line, parse_yaml, read_text
from gaide_core.transforms import is_rigid
from gaide_core.types import Array

log = logging.getLogger(__name__)

#: Every flange position farther than this (m) from the base: the file is in millimetres.
MM_THRESHOLD_M = 10.0
#: A joint value beyond this (rad, two turns) means the file is in degrees.
MAX_JOINT_RAD = 4 * np.pi
#: Pose files in a poses folder, and the columns of a poses CSV.
POSE_FILE_SUFFIXES = (".yaml", ".yml", ".json", ".txt")
POSE_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw")
#: CSV columns read as neither pose nor joints.
IGNORED_COLUMNS = ("index", "stamp", "time", "timestamp")
#: Column names read as joint numbers (j1, joint_1, q1): joints in that order, unnamed.
_NUMBERED_JOINT = re.compile(r"(?:j|joint_?|q)(\d+)", re.IGNORECASE)


@dataclass(frozen=True, kw_only=True, eq=False)
class FlangePoses:
    """The robot's pose at each image: exactly one of ``T_base_flange`` (N, 4, 4) (m) or
    ``joints`` (N, dof) (rad; m for prismatic joints).

    ``names``: the image each entry belongs to (a file name or stem), when the file gives
    them; ``joint_names``: the joints' names when the file gives them, else the columns are
    in the robot's joint order.
    """

    T_base_flange: Array | None = None  # (N, 4, 4), m
    joints: Array | None = None  # (N, dof), rad
    names: tuple[str, ...] | None = None
    joint_names: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if (self.T_base_flange is None) == (self.joints is None):
            raise CalibrationError("flange poses need exactly one of T_base_flange or joints")
        for name in ("T_base_flange", "joints"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.asarray(value, np.float64))
        if self.T_base_flange is not None and (
            self.T_base_flange.ndim != 3 or self.T_base_flange.shape[1:] != (4, 4)
        ):
            raise CalibrationError(
                f"T_base_flange must be (N, 4, 4), got {self.T_base_flange.shape}"
            )
        if self.joints is not None and self.joints.ndim != 2:
            raise CalibrationError(f"joints must be (N, dof), got {self.joints.shape}")
        if self.names is not None:
            if len(self.names) != len(self):
                raise CalibrationError(f"{len(self.names)} names for {len(self)} poses")
            twice = sorted({n for n in self.names if self.names.count(n) > 1})
            if twice:
                raise CalibrationError(f"images named more than once: {twice}")
        if self.joint_names is not None and (
            self.joints is None or len(self.joint_names) != self.joints.shape[1]
        ):
            raise CalibrationError("joint_names must name each joint column once")

    def __len__(self) -> int:
        values = self.T_base_flange if self.T_base_flange is not None else self.joints
        assert values is not None  # __post_init__ guarantees one
        return len(values)

    def take(self, indices: Sequence[int]) -> FlangePoses:
        """The entries at ``indices``, in that order."""
        idx = np.asarray(indices, np.int64)
        return FlangePoses(
            T_base_flange=None if self.T_base_flange is None else self.T_base_flange[idx],
            joints=None if self.joints is None else self.joints[idx],
            names=None if self.names is None else tuple(self.names[i] for i in idx),
            joint_names=self.joint_names,
        )


@dataclass(frozen=True)
class _Entry:
    pose: Array | None  # (4, 4)
    joints: Array | None  # (dof,)
    image: str | None
    where: str


def load_poses(path: str | os.PathLike[str], count: int | None = None) -> FlangePoses:
    """Flange poses or joint vectors, one per image, from:

    - YAML/JSON: a list (or ``{poses: [...], joint_names: [...]}``) of entries
      ``{xyz: [3], quat_xyzw: [4]}``, ``{matrix: 4x4}`` or ``{joints: [...]}``, each
      optionally with ``image: name``;
    - CSV with a header: ``x, y, z, qx, qy, qz, qw``, or joint columns (``j1..jN``,
      ``joint_1..``, ``q1..`` in number order, or the joints' names), optionally ``image``
      (``index``, ``stamp``, ``time``, ``timestamp`` are ignored);
    - a folder with one file per image, named after it (``img3.yaml`` for ``img3.png``): YAML
      or JSON as one entry above, or TXT with 16 numbers (a row-major 4x4) or 7 (x y z qx qy
      qz qw).

    Metres and radians; quaternions normalised if within 1e-3 of unit length, matrices
    orthonormalised if within 1e-3 of rigid. ``count``: the number of images, checked.
    """
    p = Path(path)
    if p.is_dir():
        where, entries, joint_names = f"poses folder {p}", _folder_entries(p), None
    elif p.suffix.lower() == ".csv":
        where = f"poses file {p}"
        entries, joint_names = _csv_entries(p, where)
    elif p.suffix.lower() in (".yaml", ".yml", ".json"):
        where = f"poses file {p}"
        entries, joint_names = _document_entries(p, where)
    elif not p.exists():
        raise CalibrationError(f"poses {p} do not exist: give a YAML, JSON or CSV file or a folder")
    else:
        raise CalibrationError(
            f"poses file {p}: unknown format {p.suffix!r}; valid: .yaml, .yml, .json, .csv, or a "
            "folder with one .yaml/.json/.txt per image"
        )
    poses = _assemble(entries, joint_names, where)
    if count is not None and len(poses) != count:
        raise CalibrationError(
            f"{where}: {len(poses)} poses for {count} images: give one per image"
        )
    log.info(
        "read %d %s from %s",
        len(poses),
        "poses" if poses.joints is None else "joint vectors",
        where,
    )
    return poses


def order_by_images(
    poses: FlangePoses, image_paths: Sequence[str | os.PathLike[str]]
) -> FlangePoses:
    """``poses`` in the order of ``image_paths``, matched by file name or stem when the poses
    name their images (else taken in order, one per image). Refuses images without a pose;
    poses of images not given are dropped."""
    images = [Path(i) for i in image_paths]
    if poses.names is None:
        if len(poses) != len(images):
            raise CalibrationError(
                f"{len(poses)} poses for {len(images)} images: give one per image"
            )
        return poses
    by_key: dict[str, list[int]] = {}
    for i, name in enumerate(poses.names):
        pure = PurePath(name)
        keys = {name, pure.name}
        if pure.suffix.lower() in IMAGE_SUFFIXES or not pure.suffix:
            keys.add(pure.stem)
        for key in keys:
            by_key.setdefault(key, []).append(i)
    order: list[int] = []
    missing: list[str] = []
    for image in images:
        hits = by_key.get(image.name) or by_key.get(image.stem) or []
        if not hits:
            missing.append(image.name)
            continue
        if len(hits) > 1:
            raise CalibrationError(
                f"image {image.name} matches several poses {[poses.names[i] for i in hits]}: "
                "name each pose's image once"
            )
        if hits[0] in order:
            raise CalibrationError(
                f"pose {poses.names[hits[0]]!r} matches two images (one is {image.name}): name "
                "each image's pose with its full file name"
            )
        order.append(hits[0])
    if missing:
        shown = ", ".join(missing[:5]) + (
            f" and {len(missing) - 5} more" if len(missing) > 5 else ""
        )
        raise CalibrationError(
            f"no pose for {len(missing)} of {len(images)} images: {shown}; poses name images "
            f"{', '.join(list(poses.names)[:5])}{', ...' if len(poses) > 5 else ''}"
        )
    if len(order) < len(poses):
        log.info("%d poses name no given image and are left out", len(poses) - len(order))
    return poses.take(order)


def _pose(data: Mapping[str, Any], where: str) -> Array:
    """(4, 4) from an entry; a matrix within 1e-3 of rigid is orthonormalised first (printed
    matrices lose digits), then ``pose_from_dict`` checks it."""
    if "matrix" in data:
        try:
            T = np.asarray(data["matrix"], np.float64)
        except (TypeError, ValueError) as err:
            raise CalibrationError(f"{where}: matrix is not numeric: {err}") from err
        if T.shape == (4, 4) and is_rigid(T, tol=1e-3):
            U, _, Vt = np.linalg.svd(T[:3, :3])
            T = T.copy()
            T[:3, :3], T[3] = U @ Vt, [0.0, 0.0, 0.0, 1.0]
        elif T.shape == (16,):
            raise CalibrationError(f"{where}: matrix must be 4x4 (rows of 4), got 16 numbers")
        data = {"matrix": T}
    return pose_from_dict(dict(data), where)


def _entry(data: Any, where: str, image: str | None = None) -> _Entry:
    if not isinstance(data, Mapping):
        raise CalibrationError(
            f"{where} must be a mapping with xyz + quat_xyzw, matrix (4x4) or joints, got "
            f"{one_line(repr(data))[:80]}"
        )
    if image is None and data.get("image") is not None:
        if not isinstance(data["image"], (str, int)):
            raise CalibrationError(f"{where}: image must be a file name, got {data['image']!r}")
        image = str(data["image"])
    if "joints" in data:
        if {"matrix", "xyz", "quat_xyzw"} & data.keys():
            raise CalibrationError(f"{where} gives both joints and a pose: give one")
        q = numbers(data["joints"], f"{where}: joints")
        if q.ndim != 1 or q.size == 0:
            raise CalibrationError(
                f"{where}: joints must be a list of numbers, got {data['joints']!r}"
            )
        return _Entry(None, q, image, where)
    return _Entry(_pose(data, where), None, image, where)


def _document_entries(path: Path, where: str) -> tuple[list[_Entry], tuple[str, ...] | None]:
    if path.suffix.lower() == ".json":
        data = load_json(path, "poses file", CalibrationError)
    else:
        data = parse_yaml(read_text(path, "poses file", CalibrationError), where, CalibrationError)
    joint_names = None
    if isinstance(data, Mapping) and "poses" in data:
        names = data.get("joint_names")
        if names is not None:
            if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
                raise CalibrationError(f"{where}: joint_names must be a list of names")
            joint_names = tuple(names)
        data = data["poses"]
    if not isinstance(data, list) or not data:
        raise CalibrationError(
            f"{where} must hold a non-empty list of poses (or poses: [...]), each "
            "{xyz: [3], quat_xyzw: [4]}, {matrix: 4x4} or {joints: [...]}, optionally with image"
        )
    return [_entry(e, f"{where}: entry {i + 1}") for i, e in enumerate(data)], joint_names


def _csv_entries(path: Path, where: str) -> tuple[list[_Entry], tuple[str, ...] | None]:
    text = read_text(path, "poses file", CalibrationError)
    lines = [
        (n, line)
        for n, line in enumerate(text.splitlines(), 1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if len(lines) < 2:
        raise CalibrationError(f"{where} needs a header line and at least one row of values")
    first = lines[0][1]
    delimiter = next((d for d in (",", "\t", ";") if d in first), ",")
    rows = list(csv.reader([line for _, line in lines], delimiter=delimiter))
    header = [h.strip() for h in rows[0]]
    lower = [h.lower() for h in header]
    twice = sorted({h for h in lower if lower.count(h) > 1})
    if twice:
        raise CalibrationError(f"{where}: columns {twice} appear more than once")
    image_col = lower.index("image") if "image" in lower else None
    used = [i for i, h in enumerate(lower) if h != "image" and h not in IGNORED_COLUMNS]
    joint_names: tuple[str, ...] | None = None
    is_pose = bool(set(POSE_COLUMNS) & set(lower))
    if is_pose:
        missing = [c for c in POSE_COLUMNS if c not in lower]
        other = [header[i] for i in used if lower[i] not in POSE_COLUMNS]
        if missing or other:
            raise CalibrationError(
                f"{where}: a pose CSV has the columns {', '.join(POSE_COLUMNS)} (and optionally "
                f"image); missing {missing}, unknown {other}"
            )
        used = [lower.index(c) for c in POSE_COLUMNS]
    elif not used:
        raise CalibrationError(
            f"{where} has no pose columns ({', '.join(POSE_COLUMNS)}) and no joint columns "
            f"(j1..jN, joint_1.., or the joints' names); header: {header}"
        )
    else:
        numbers = [_NUMBERED_JOINT.fullmatch(header[i]) for i in used]
        if all(numbers):
            by_number = sorted(zip((int(m[1]) for m in numbers if m), used, strict=True))
            got = [k for k, _ in by_number]
            if got != list(range(got[0], got[0] + len(got))) or got[0] not in (0, 1):
                raise CalibrationError(
                    f"{where}: numbered joint columns must run 1..N (or 0..N-1) without gaps, "
                    f"got {[header[i] for _, i in by_number]}"
                )
            used = [i for _, i in by_number]
        else:
            joint_names = tuple(header[i] for i in used)
    entries = []
    for (n, _), row in zip(lines[1:], rows[1:], strict=True):
        at = f"{where} line {n}"
        if len(row) != len(header):
            raise CalibrationError(f"{at}: {len(row)} values for {len(header)} columns")
        values = np.array([_cell(row[i], at, header[i]) for i in used])
        image = row[image_col].strip() if image_col is not None else None
        if is_pose:
            entry = {"xyz": values[:3], "quat_xyzw": values[3:]}
            entries.append(_Entry(_pose(entry, at), None, image or None, at))
        else:
            entries.append(_Entry(None, values, image or None, at))
    return entries, joint_names


def _cell(text: str, where: str, column: str | None = None) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value):
        at = where if column is None else f"{where}, column {column}"
        raise CalibrationError(f"{at}: {text.strip()!r} is not a number")
    return value


def _folder_entries(folder: Path) -> list[_Entry]:
    files = [
        f
        for f in folder.iterdir()
        if f.is_file() and f.suffix.lower() in POSE_FILE_SUFFIXES and not f.name.startswith(".")
    ]
    if not files:
        raise CalibrationError(
            f"poses folder {folder} holds no pose files: give one .yaml, .json or .txt per "
            "image, named after the image (img3.yaml for img3.png)"
        )
    stems: dict[str, Path] = {}
    for f in files:
        if f.stem in stems:
            raise CalibrationError(
                f"poses folder {folder}: {stems[f.stem].name} and {f.name} both give the pose of "
                f"image {f.stem}: keep one"
            )
        stems[f.stem] = f
    entries = []
    for stem in sorted(stems, key=natural_key):
        f = stems[stem]
        where = f"pose file {f}"
        if f.suffix.lower() == ".txt":
            entries.append(_Entry(_txt_pose(f, where), None, stem, where))
        elif f.suffix.lower() == ".json":
            entries.append(_entry(load_json(f, "pose file", CalibrationError), where, stem))
        else:
            text = read_text(f, "pose file", CalibrationError)
            entries.append(_entry(parse_yaml(text, where, CalibrationError), where, stem))
    return entries


def _txt_pose(path: Path, where: str) -> Array:
    text = read_text(path, "pose file", CalibrationError)
    cells = [c for c in re.split(r"[\s,;\[\]]+", text) if c]
    values = np.array([_cell(c, where) for c in cells])
    if values.size == 16:
        return _pose({"matrix": values.reshape(4, 4)}, where)
    if values.size == 7:
        return _pose({"xyz": values[:3], "quat_xyzw": values[3:]}, where)
    raise CalibrationError(
        f"{where} holds {values.size} numbers; a pose text file holds 16 (a 4x4 matrix, row "
        "by row) or 7 (x y z qx qy qz qw, metres)"
    )


def _assemble(
    entries: Sequence[_Entry], joint_names: tuple[str, ...] | None, where: str
) -> FlangePoses:
    kinds = {e.joints is not None for e in entries}
    if len(kinds) > 1:
        first_joints = next(e for e in entries if e.joints is not None)
        first_pose = next(e for e in entries if e.pose is not None)
        raise CalibrationError(
            f"{where} mixes joint vectors ({first_joints.where}) and poses ({first_pose.where}): "
            "give one kind"
        )
    named = [e.image is not None for e in entries]
    if any(named) and not all(named):
        unnamed = [e.where for e in entries if e.image is None][:3]
        raise CalibrationError(
            f"{where}: some entries name their image and others do not ({', '.join(unnamed)}): "
            "name every entry's image or none"
        )
    names = tuple(str(e.image) for e in entries) if all(named) else None
    if names is not None and len(set(names)) < len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise CalibrationError(f"{where}: images named more than once: {twice}")
    if kinds == {True}:
        dof = {len(e.joints) for e in entries if e.joints is not None}
        if len(dof) > 1:
            raise CalibrationError(f"{where}: joint vectors differ in length {sorted(dof)}")
        joints = np.array([e.joints for e in entries])
        worst = float(np.abs(joints).max())
        if worst > MAX_JOINT_RAD:
            raise CalibrationError(
                f"{where}: a joint value of {worst:g} looks like degrees; give radians"
            )
        if joint_names is not None and len(joint_names) != joints.shape[1]:
            raise CalibrationError(
                f"{where}: {len(joint_names)} joint_names for {joints.shape[1]} joint values"
            )
        return FlangePoses(joints=joints, names=names, joint_names=joint_names)
    T = np.array([e.pose for e in entries])
    dist = np.linalg.norm(T[:, :3, 3], axis=1)
    if np.all(dist > MM_THRESHOLD_M):
        raise CalibrationError(
            f"{where}: every flange position is {dist.min():.0f}..{dist.max():.0f} from the "
            f"base: the translations look like millimetres; give metres"
        )
    return FlangePoses(T_base_flange=T, names=names)
