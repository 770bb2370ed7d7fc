"""One source of defaults: the config classes. ``run.yaml`` documents them and the commands'
flags show them; neither may drift from the classes."""

from __future__ import annotations

import dataclasses

import pytest

from execution.ros2_goal import Ros2GoalCfg
from execution.sim_cfg import SimCfg
from execution.timing_cfg import TimingCfg
from execution.urscript import UrScriptCfg
from gaide.cli import build_parser
from gaide.pipeline.config import PlanningCfg, RunCfg
from gaide.pipeline.config_io import DEFAULTS, default_dict, load_cfg, read_yaml
from gaide_core.errors import ConfigError
from perception.cloud_cfg import CloudCfg


def test_run_yaml_documents_exactly_the_class_defaults_in_their_order() -> None:
    documented, defaults = read_yaml(DEFAULTS), default_dict()
    assert documented == defaults
    assert list(documented) == list(defaults)
    for section, body in defaults.items():
        if isinstance(body, dict):
            assert list(documented[section]) == list(body), section


def test_run_sections_extend_the_library_settings() -> None:
    run = RunCfg()
    assert isinstance(run.timing, TimingCfg) and run.timing == TimingCfg()
    for f in dataclasses.fields(CloudCfg):
        assert getattr(run.perception, f.name) == getattr(CloudCfg(), f.name), f.name
    # a run holds the goal a little and models the cloud finer: the only two differences
    differ = [
        f.name
        for f in dataclasses.fields(SimCfg)
        if getattr(run.simulate, f.name) != getattr(SimCfg(), f.name)
    ]
    assert sorted(differ) == ["settle_s", "voxel_m"]
    # the export section: the URScript program's and the ros2_control goal's settings as such
    for lib in (UrScriptCfg, Ros2GoalCfg):
        assert isinstance(run.export, lib)
        for f in dataclasses.fields(lib):
            assert getattr(run.export, f.name) == getattr(lib(), f.name), f.name
    assert list(run.as_dict()["export"])[:2] == ["formats", "storage"]


def _defaults(*command: str) -> dict[str, object]:
    parser = build_parser()
    for name in command:
        sub = next(a for a in parser._actions if isinstance(getattr(a, "choices", None), dict))
        parser = sub.choices[name]  # type: ignore[index]
    return {a.dest: a.default for a in parser._actions}


def test_command_flags_default_to_the_class_values() -> None:
    timing, sim = TimingCfg(), SimCfg()
    flags = _defaults("time")
    assert flags["rate"] == timing.rate_hz and flags["mode"] == timing.mode.value
    assert flags["velocity_scale"] == timing.velocity_scale
    assert flags["jerk_scale"] == timing.jerk_scale
    # gaide simulate replays as a run simulates: the run's section, not the library's
    replay, run_sim = _defaults("simulate"), RunCfg().simulate
    assert replay["settle"] == run_sim.settle_s != sim.settle_s
    assert replay["voxel"] == run_sim.voxel_m != sim.voxel_m and replay["crop"] == run_sim.crop_m
    urscript, goal = UrScriptCfg(), Ros2GoalCfg()
    assert flags["urscript_mode"] == urscript.urscript_mode.value
    assert flags["servoj_period"] == urscript.servoj_period_s
    assert flags["ros2_controller"] == goal.ros2_controller
    assert flags["goal_rate"] == goal.goal_rate_hz
    assert _defaults("perceive")["voxel"] == CloudCfg().voxel
    assert _defaults("plan")["budget"] == PlanningCfg().budget_s


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("timing.rate_hz", 0, r"timing\.rate_hz must be a number in \[1, 2000\] Hz"),
        ("timing.blend_levels", 1, r"timing\.blend_levels"),
        ("perception.outlier_std", -1, r"perception\.outlier_std"),
        ("perception.workspace_min", [2, 2, 2], r"perception\.workspace_min .* below"),
        ("simulate.velocity_gain", 2, r"simulate\.velocity_gain"),
        ("simulate.crop_m", -1, r"simulate\.crop_m"),
        ("export.servoj_period_s", 0.003, r"export\.servoj_period_s must be a whole number"),
        ("export.urscript_mode", "speedj", r"export\.urscript_mode must be one of"),
        ("export.ros2_controller", "a b", r"export\.ros2_controller must be a ROS name"),
        ("export.formats", ["csv", "txt"], r"export\.formats must be one of .*'urscript'"),
    ],
)
def test_a_library_setting_out_of_range_names_its_section(
    key: str, value: object, message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        load_cfg(overrides=[(key, value)])


def test_the_effective_settings_print_plain_values() -> None:
    shown = RunCfg().as_dict()
    assert shown["timing"]["mode"] == "blended"
    assert RunCfg.from_dict(shown) == RunCfg()
