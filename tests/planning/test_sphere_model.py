from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import trimesh

from gaide_core.errors import RobotModelError
from planning.robot_model import RobotModel, load_robot
from planning.sphere_model import SphereModel, frame_mismatch
from planning.spherize import SpherizeCfg, generate_spheres
from tests.conftest import shared_data


def _uncovered(mesh: trimesh.Trimesh, model: SphereModel, link: str, n: int, seed: int) -> int:
    idx = model.of_link(link)
    pts, _ = trimesh.sample.sample_surface(mesh, n, seed=seed)
    pts = np.concatenate([pts, mesh.vertices])
    d2 = np.sum((pts[:, None, :] - model.centers[idx][None]) ** 2, axis=-1)
    return int(np.sum(np.all(d2 > model.radii[idx][None] ** 2 + 1e-12, axis=1)))


def test_shipped_ur5_spheres_cover_every_link_mesh(robot: RobotModel, spheres: SphereModel) -> None:
    assert len(spheres) <= 60
    for link, mesh in robot.link_meshes.items():
        assert _uncovered(mesh, spheres, link, 4000, seed=7) == 0, f"{link} pokes out"


def test_generated_spheres_cover_a_small_robot(tmp_path: Path) -> None:
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("""<robot name="arm">
      <link name="base"><collision><geometry><box size="0.2 0.2 0.05"/></geometry></collision></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
        <origin xyz="0 0 0.05"/><axis xyz="0 0 1"/>
        <limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
      <link name="l1"><collision><origin xyz="0 0 0.2"/>
        <geometry><cylinder radius="0.04" length="0.4"/></geometry></collision></link>
    </robot>""")
    cfg = tmp_path / "robot.yaml"
    cfg.write_text(f"urdf: {urdf}\nend_effector: l1\n")
    robot = load_robot(cfg)
    model = generate_spheres(robot, SpherizeCfg(max_spheres=12))
    assert 2 <= len(model) <= 12
    for link, mesh in robot.link_meshes.items():
        assert _uncovered(mesh, model, link, 3000, seed=3) == 0
    # the tube gets several spheres, each not much fatter than the tube
    tube = model.of_link("l1")
    assert len(tube) >= 3 and model.radii[tube].max() < 0.09


def test_yaml_round_trip(spheres: SphereModel, tmp_path: Path) -> None:
    path = tmp_path / "spheres.yml"
    spheres.save(path)
    back = SphereModel.load(path)
    assert back.links == spheres.links
    np.testing.assert_allclose(back.centers, spheres.centers, atol=1e-6)
    np.testing.assert_allclose(back.radii, spheres.radii, atol=1e-6)


def test_curobo_nested_layout_and_unused_slots(tmp_path: Path) -> None:
    path = tmp_path / "robot.yml"
    path.write_text("""robot_cfg:
  kinematics:
    collision_spheres:
      forearm_link:
        - "center": [0.0, 0.0, 0.1]
          "radius": 0.05
        - "center": [0.0, 0.0, 0.0]
          "radius": -10.0
""")
    model = SphereModel.load(path)
    assert model.links == ("forearm_link",)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("just text", "no 'collision_spheres' mapping"),
        ("collision_spheres:\n  l: [{center: [0, 0], radius: 1}]\n", "center needs 3 values"),
        ("collision_spheres:\n  l: [{radius: 1}]\n", "needs center"),
        ("collision_spheres: {a: [}", "not valid YAML"),
        ("collision_spheres:\n  l: [{center: [0, 0, 0], radius: .nan}]\n", "not finite"),
        ("collision_spheres:\n  l: [{center: [0, .inf, 0], radius: 0.1}]\n", "not finite"),
    ],
)
def test_bad_sphere_files(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "s.yml"
    path.write_text(text)
    with pytest.raises(RobotModelError, match=message):
        SphereModel.load(path)


def test_unknown_link_is_refused(robot: RobotModel) -> None:
    model = SphereModel(("gripper",), np.zeros((1, 3)), np.ones(1))
    with pytest.raises(RobotModelError, match="valid links"):
        model.check_against(robot)


def test_third_party_spherized_urdf_imports(robot: RobotModel, rng: np.random.Generator) -> None:
    urdf = shared_data("robots/vamp_ur5_spherized.urdf")
    for q in robot.sample_uniform(rng, 5):
        assert frame_mismatch(urdf, robot, q) < 1e-6
    model = SphereModel.from_spherized_urdf(urdf, robot)
    assert len(model) == 40
    model.check_against(robot)
    # the gripper's spheres ride on the last joint, in front of the flange
    from planning.collision import SphereCollisionChecker

    checker = SphereCollisionChecker(robot, model)
    q = robot.named_configuration("home")
    centers = checker.sphere_centers(q[None])[0]
    flange = robot.frame_pose(q, "tool0")
    gripper = [i for i, link in enumerate(model.links) if link in ("ee_link", "wrist_3_link")]
    ahead = (centers[gripper] - flange[:3, 3]) @ flange[:3, 2]
    assert ahead.max() > 0.1  # Robotiq fingers reach well past the flange


@pytest.mark.parametrize(
    ("radius", "says"),
    [("nan", "needs a finite radius > 0 m"), ("-0.05", "needs a finite radius > 0 m"),
     ("wide", "without a numeric radius")],
)  # fmt: skip
def test_a_spherized_urdf_sphere_without_a_size_is_refused(
    robot: RobotModel, tmp_path: Path, radius: str, says: str
) -> None:
    text = shared_data("robots/vamp_ur5_spherized.urdf").read_text()
    first = re.search(r'<sphere radius="[^"]*"', text)
    assert first is not None
    bad = tmp_path / "bad.urdf"
    bad.write_text(text[: first.start()] + f'<sphere radius="{radius}"' + text[first.end() :])
    with pytest.raises(RobotModelError, match=says):
        SphereModel.from_spherized_urdf(bad, robot)


def test_spherized_urdf_spheres_follow_its_own_kinematics(
    robot: RobotModel, rng: np.random.Generator
) -> None:
    """Every imported sphere, carried by our FK, sits where the spherized URDF's own
    kinematics puts it (in its base_link's frame: the URDF mounts the arm 0.9144 m up and
    turned), base spheres included."""
    import pinocchio as pin

    from planning.collision import SphereCollisionChecker

    urdf = shared_data("robots/vamp_ur5_spherized.urdf")
    model = SphereModel.from_spherized_urdf(urdf, robot)
    checker = SphereCollisionChecker(robot, model)
    theirs = pin.buildModelFromUrdf(str(urdf))
    data = theirs.createData()
    root = ET.parse(urdf).getroot()
    spheres = [
        (
            link.attrib["name"],
            np.array([float(v) for v in col.find("origin").attrib["xyz"].split()]),
        )
        for link in root.iter("link")
        for col in link.iter("collision")
        if col.find("geometry/sphere") is not None
    ]
    assert len(spheres) == len(model)
    base = theirs.getFrameId("base_link")
    assert any(robot.links[link].joint_id == 0 for link in model.links)  # base spheres exist
    for q in [*robot.sample_uniform(rng, 4), robot.named_configuration("home")]:
        q_theirs = np.zeros(theirs.nq)
        for name, value in zip(robot.joint_names, q, strict=True):
            q_theirs[theirs.joints[theirs.getJointId(name)].idx_q] = value
        pin.framesForwardKinematics(theirs, data, q_theirs)
        expected = np.array(
            [(data.oMf[base].inverse() * data.oMf[theirs.getFrameId(n)]).act(p) for n, p in spheres]
        )
        ours = checker.sphere_centers(q[None])[0]
        T_base = robot.frame_pose(q, "base_link")
        ours_in_base = (ours - T_base[:3, 3]) @ T_base[:3, :3]
        assert np.abs(ours_in_base - expected).max() < 1e-6


def test_a_config_takes_a_spherized_urdf_as_its_spheres(robot: RobotModel) -> None:
    urdf = shared_data("robots/vamp_ur5_spherized.urdf")
    from_urdf = SphereModel.load_for(urdf, robot)
    direct = SphereModel.from_spherized_urdf(urdf, robot)
    assert from_urdf.links == direct.links and np.array_equal(from_urdf.centers, direct.centers)
    assert len(SphereModel.load_for(robot.config.spheres, robot)) == len(  # type: ignore[arg-type]
        SphereModel.load(robot.config.spheres)  # type: ignore[arg-type]
    )
