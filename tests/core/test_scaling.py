"""Scene units: lengths stated in the original's units, converted by one function."""

from __future__ import annotations

import dataclasses

import pytest

from amex.core.scaling import SCALE_KEY, scale_value, to_scene_units
from amex.experiment.config import ControllerConfig, RunConfig
from amex.methods import METHODS
from amex.sim.scenario import ScenarioConfig


def _marked(cls) -> dict[str, int]:
    fields = dataclasses.fields(cls)
    return {f.name: f.metadata[SCALE_KEY] for f in fields if SCALE_KEY in f.metadata}


def test_the_scene_dependent_fields_are_marked():
    assert _marked(METHODS["cr"].config_class) == {"final_axis": 2, "collision_margin": 1}
    assert _marked(METHODS["dmp"].config_class) == {"min_amplitude": 1}
    assert _marked(METHODS["dmp_ps"].config_class) == {"min_amplitude": 1, "beta_ps": -2}
    assert _marked(ControllerConfig) == {
        "margin": 1, "proxy_arm_radii": 1, "proxy_obstacle_radius": 1,
    }  # fmt: skip
    assert set(_marked(ScenarioConfig)) == {
        "reference_offset", "box_size", "goal_speed_std", "plane_offset", "obstacle_radius",
        "obstacle_speed_std",
    }  # fmt: skip
    assert _marked(RunConfig) == {"stop_radius": 1}


def test_the_pandas_method_values_are_the_ones_tuned_at_scale_0_2():
    scale = RunConfig().scenario.scale
    cr = to_scene_units(METHODS["cr"].config_class(), scale)
    assert (cr.final_axis, cr.collision_margin) == (400.0, 0.1 * 0.2)
    assert to_scene_units(METHODS["dmp"].config_class(), scale).min_amplitude == 0.05
    assert to_scene_units(METHODS["dmp_ps"].config_class(), scale).beta_ps == 1000.0


def test_plan_and_controller_margins_are_the_same_number():
    config = RunConfig()
    config.method = METHODS["cr"].config_class()
    assert config.method_config().collision_margin == config.gains().margin


def test_scale_one_changes_nothing_and_nested_configs_are_converted():
    config = RunConfig()
    config.method = METHODS["cr"].config_class()
    assert to_scene_units(config, 1.0) == config
    scene = to_scene_units(config, 0.5)
    assert scene.scenario.box_size == [0.35, 0.4, 0.9]
    assert scene.controller.margin == 0.05 and scene.method.final_axis == 2500.0
    assert scene.controller.col == config.controller.col  # gains carry no length


@pytest.mark.parametrize(("power", "expected"), [(0, 3.0), (1, 0.6000000000000001), (-2, 75.0)])
def test_scale_value_multiplies_once_per_power(power, expected):
    assert scale_value(3.0, 0.2, power) == expected
