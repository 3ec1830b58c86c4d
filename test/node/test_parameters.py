"""config/frisicp.yaml, the declared parameters and the pipeline settings agree."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from frisicp_ros.node import parameters
from frisicp_ros.stream.pipeline import PipelineSettings

ROOT = Path(__file__).resolve().parents[2]


def test_yaml_lists_every_parameter_with_its_default():
    loaded = yaml.safe_load((ROOT / "config" / "frisicp.yaml").read_text())["/**"]["ros__parameters"]
    assert loaded == parameters.defaults()
    assert set(parameters.SPECS) == set(loaded)
    assert set(PipelineSettings.names()) <= set(loaded)


def test_settings_from_rejects_with_the_reason_and_accepts_valid_values():
    values = parameters.defaults()
    assert parameters.settings_from(values) == PipelineSettings()
    with pytest.raises(ValueError, match="model_qos must be one of"):
        parameters.settings_from({**values, "model_qos": "latched"})
    with pytest.raises(ValueError, match="coarsest_points"):
        parameters.settings_from({**values, "coarsest_points": 5})
    assert parameters.settings_from({**values, "dims": 2, "pairing": "synchronized"}).dims == 2


def test_descriptors_carry_descriptions_and_ranges():
    overlap = parameters.descriptor("overlap", parameters.SPECS["overlap"])
    assert overlap.description and overlap.floating_point_range[0].to_value == 1.0
    levels = parameters.descriptor("levels", parameters.SPECS["levels"])
    assert levels.integer_range[0].from_value == 1
    assert "frisicp" in parameters.descriptor("method", parameters.SPECS["method"]).additional_constraints
    assert parameters.descriptor("model_qos", parameters.SPECS["model_qos"]).read_only


def test_every_core_option_is_a_parameter():
    from dataclasses import fields as dataclass_fields

    from frisicp_core import ConvergenceCriteria, RegistrationConfig
    from frisicp_ros.stream.pipeline import NOT_PARAMETERS

    core = {f.name for f in dataclass_fields(RegistrationConfig)} - set(NOT_PARAMETERS)
    core |= {f.name for f in dataclass_fields(ConvergenceCriteria)}
    assert core <= set(parameters.SPECS), sorted(core - set(parameters.SPECS))
    config = PipelineSettings().registration_config()
    assert config == RegistrationConfig(drop_nonfinite=False)  # same defaults as the core
