"""Checkpoints: the weights with everything needed to rebuild and check the model (kind,
sizes, robot, embodiment), and a model card beside each (data, steps, time, device, losses)."""

from __future__ import annotations

import hashlib
import io
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import torch
from torch import nn

from gaide_core.atomic import write_files_atomic
from gaide_core.errors import ModelError
from planning.neural.embodiment import Embodiment
from planning.neural.models import MODEL_KINDS, ModelCfg, build_model
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel

log = logging.getLogger(__name__)

FORMAT = "gaide-checkpoint/1"
WEIGHTS_DIR = Path(__file__).resolve().parent.parent / "data" / "weights"


def shipped_checkpoint(kind: str) -> Path:
    """The repository's trained weights for ``kind`` (the embedded default)."""
    if kind not in MODEL_KINDS:
        raise ModelError(f"unknown model '{kind}'; valid: {list(MODEL_KINDS)}")
    return WEIGHTS_DIR / f"{kind}.pt"


def robot_signature(robot: RobotModel) -> dict[str, Any]:
    """What a checkpoint must match: the joint names and limits of the robot, and its
    kinematics (``kinematics``: per joint, the placement in its parent joint's frame (xyz in
    m, quaternion xyzw) and the motion it allows in its own frame (the Jacobian column:
    linear, angular), so an arm with the same joint names but other link lengths or axes
    (a UR10 for a UR5) does not pass)."""
    model = robot.model
    data = model.createData()
    q0 = pin.neutral(model)
    pin.computeJointJacobians(model, data, q0)
    kinematics = []
    for i in range(1, model.njoints):
        placement = model.jointPlacements[i]
        J = pin.getJointJacobian(model, data, i, pin.ReferenceFrame.LOCAL)
        motion = J[:, model.joints[i].idx_v] if model.joints[i].nv == 1 else np.zeros(6)
        quat = pin.Quaternion(placement.rotation).coeffs()
        kinematics.append([round(float(v), 7) for v in (*placement.translation, *quat, *motion)])
    return {
        "joints": [str(n) for n in model.names[1:]],
        "dof": robot.dof,
        "lower": [round(float(x), 6) for x in robot.lower],
        "upper": [round(float(x), 6) for x in robot.upper],
        "kinematics": kinematics,
        "spheres": sphere_model_hash(robot),
    }


def sphere_model_hash(robot: RobotModel) -> str | None:
    """sha256 of the robot config's sphere model as written in cuRobo's layout (the same
    spheres give the same hash whatever file they came from); None when the config names
    no sphere file."""
    if robot.config.spheres is None:
        return None
    spheres = SphereModel.load_for(robot.config.spheres, robot)
    return hashlib.sha256(spheres.to_yaml().encode()).hexdigest()


#: Placements and axes closer than this (m, or unit-vector components) count as the same.
KINEMATICS_TOL = 1e-5


def signature_difference(theirs: dict[str, Any], ours: dict[str, Any]) -> str | None:
    """What differs between a checkpoint's robot and this one, in words, or None."""
    if theirs.get("joints") != ours["joints"] or theirs.get("dof") != ours["dof"]:
        return f"joints {theirs.get('joints')} there, {ours['joints']} here"
    kin = theirs.get("kinematics")
    if kin is None:
        return None  # a checkpoint from before signatures held the kinematics
    for name, a, b in zip(ours["joints"], kin, ours["kinematics"], strict=True):
        ta, tb = np.asarray(a[:3]), np.asarray(b[:3])
        if np.abs(ta - tb).max() > KINEMATICS_TOL:
            return (
                f"joint {name} sits {np.linalg.norm(ta):.4f} m from its parent there, "
                f"{np.linalg.norm(tb):.4f} m here (link lengths differ)"
            )
        qa, qb = np.asarray(a[3:7]), np.asarray(b[3:7])
        if min(np.abs(qa - qb).max(), np.abs(qa + qb).max()) > KINEMATICS_TOL:
            return f"joint {name} is mounted at another orientation there"
        if np.abs(np.asarray(a[7:]) - np.asarray(b[7:])).max() > KINEMATICS_TOL:
            return f"joint {name} moves about/along another axis there ({a[7:]} vs {b[7:]})"
    return None


@dataclass
class Checkpoint:
    kind: str
    cfg: ModelCfg
    embodiment: Embodiment
    robot: dict[str, Any]
    state: dict[str, Any]
    step: int = 0
    optimizer: dict[str, Any] | None = None
    card: dict[str, Any] = field(default_factory=dict)

    def model(self) -> nn.Module:
        m = build_model(self.kind, self.cfg, self.embodiment, int(self.robot["dof"]))
        try:
            m.load_state_dict(self.state)
        except RuntimeError as err:
            # torch lists every mismatched tensor on its own line: keep the first
            first = next((ln.strip() for ln in str(err).splitlines() if ln.strip()), "")
            raise ModelError(
                f"the checkpoint's weights do not fit a {self.kind} model of its sizes ({first})"
            ) from err
        return m


def save_checkpoint(path: str | Path, ckpt: Checkpoint) -> str:
    """Write the checkpoint and its card (``<path>.card.json``) atomically, both or neither
    (the card holds the checkpoint's sha256); returns that sha256."""
    buf = io.BytesIO()
    torch.save(
        {
            "format": FORMAT,
            "kind": ckpt.kind,
            "cfg": ckpt.cfg.to_dict(),
            "embodiment": ckpt.embodiment.to_dict(),
            "robot": ckpt.robot,
            "state": ckpt.state,
            "step": ckpt.step,
            "optimizer": ckpt.optimizer,
            "card": ckpt.card,
        },
        buf,
    )
    data = buf.getvalue()
    digest = hashlib.sha256(data).hexdigest()
    card = dict(ckpt.card, sha256=digest, kind=ckpt.kind, step=ckpt.step)
    write_files_atomic(
        [(path, data), (card_path(path), json.dumps(card, indent=1).encode())], ModelError
    )
    return digest


def card_path(path: str | Path) -> Path:
    p = Path(path)
    return p.with_name(p.name + ".card.json")


def load_checkpoint(
    path: str | Path, robot: RobotModel | None = None, kind: str | None = None
) -> Checkpoint:
    """Read a checkpoint; with ``robot`` / ``kind`` given, refuse one made for another."""
    p = Path(path)
    if not p.is_file():
        raise ModelError(f"checkpoint {p} does not exist (train one with `gaide train`)")
    try:
        raw = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises many types for a corrupt file
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise ModelError(f"checkpoint {p} is corrupt or not a torch file ({first})") from err
    if not isinstance(raw, dict) or raw.get("format") != FORMAT:
        raise ModelError(f"{p} is not a GAIDE checkpoint (expected format {FORMAT})")
    try:
        ckpt = Checkpoint(
            kind=raw["kind"],
            cfg=ModelCfg(**raw["cfg"]),
            embodiment=Embodiment.from_dict(raw["embodiment"]),
            robot=raw["robot"],
            state=raw["state"],
            step=int(raw["step"]),
            optimizer=raw.get("optimizer"),
            card=raw.get("card") or {},
        )
    except (KeyError, TypeError, ValueError) as err:
        raise ModelError(f"checkpoint {p} is incomplete ({err})") from err
    bad = [
        name
        for name, tensor in ckpt.state.items()
        if not isinstance(tensor, torch.Tensor)
        or (tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()))
    ]
    if bad:
        raise ModelError(
            f"checkpoint {p} has weights that are not finite numbers ({', '.join(bad[:3])}"
            f"{', ...' if len(bad) > 3 else ''}): the training diverged or the file is damaged"
        )
    if kind is not None and ckpt.kind != kind:
        raise ModelError(f"checkpoint {p} holds a {ckpt.kind} model, not {kind}")
    if robot is not None:
        ours = robot_signature(robot)
        differs = signature_difference(ckpt.robot, ours)
        if differs is not None:
            raise ModelError(
                f"checkpoint {p} was trained for another robot: {differs}; the classical and "
                "compiled planners (rrtc, gaide-hybrid's classical part, the OMPL baselines) "
                "work for any robot, or train weights for this one with `gaide train --robot`"
            )
        theirs = ckpt.robot.get("spheres")
        if theirs is not None and theirs != ours["spheres"]:
            # The same arm with another collision model: its labels were collision-free for
            # other spheres. Usable, but the user should know.
            log.warning(
                "checkpoint %s was trained with another sphere model of this robot (its "
                "proposals may sit nearer obstacles than these spheres allow)",
                p,
            )
    return ckpt


def file_sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
