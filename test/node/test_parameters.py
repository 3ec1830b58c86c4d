"""One settings table: config/frisicp.yaml, the node's parameters, the CLI options and the core agree."""

from __future__ import annotations

import re
from dataclasses import fields, replace
from pathlib import Path

import pytest
import yaml

from frisicp_core import ConvergenceCriteria, RegistrationConfig
from frisicp_core.config import Tolerance
from frisicp_core.kdtree import BACKENDS
from frisicp_ros.node import parameters
from frisicp_ros.stream import settings
from frisicp_ros.stream.settings import OPTIONS_BY_NAME, PipelineSettings, Surface, settings_from

ROOT = Path(__file__).resolve().parents[2]


def test_yaml_file_is_the_one_generated_from_the_table():
    text = (ROOT / "config" / "frisicp.yaml").read_text()
    assert text == settings.render_yaml(), "config/frisicp.yaml is stale: run `make config`"


@pytest.mark.parametrize("document", ["docs/node.md", "README.md"])
def test_docs_list_every_parameter_with_its_type_from_the_table(document):
    text = (ROOT / document).read_text()
    assert settings.with_table(text) == text, f"{document}'s parameter table is stale: run `make config`"
    for row in settings.options_for(settings.Surface.NODE):
        assert f"| `{row.name}` | {row.kind.__name__} |" in text


def test_yaml_lists_every_parameter_with_its_default():
    loaded = yaml.safe_load((ROOT / "config" / "frisicp.yaml").read_text())["/**"]["ros__parameters"]
    assert loaded == settings.defaults(Surface.NODE)
    assert set(parameters.NAMES) == set(loaded)
    stream_names = {f.name for f in fields(PipelineSettings)} - {"registration"}
    assert stream_names <= set(loaded)
    for name in ("bag", "bag_rate", "bag_delay", "bag_wait_for_subscribers", "bag_exit_on_end"):
        assert name in loaded  # the replay's parameters are in the table like every other


def test_settings_from_rejects_with_the_reason_and_accepts_valid_values():
    values = settings.defaults(Surface.NODE)
    assert settings_from(values) == PipelineSettings.create()
    with pytest.raises(ValueError, match="model_qos must be one of"):
        settings_from({**values, "model_qos": "latched"})
    with pytest.raises(ValueError, match="coarsest_points"):
        settings_from({**values, "coarsest_points": 5})
    with pytest.raises(ValueError, match="unknown option"):
        settings_from({**values, "coarse_points": 500})
    assert settings_from({**values, "dims": 2, "pairing": "synchronized"}).dims == 2


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        # The grid overflowed float64 and each cloud cost a sort and a RuntimeWarning.
        ("voxel_size", 1e-300, "voxel_size must be 0 (off) or at least 1e-06, got 1e-300"),
        # Accepted, after which every pair was rejected as a frame mismatch.
        ("model_frame", "m" * 5000, "model_frame must be a frame id of at most 255 printable"),
        ("data_frame", "base link", "data_frame must be a frame id of at most 255 printable"),
        ("data_frame", "lidar\n", "data_frame must be a frame id"),
    ],
)
def test_harmful_values_are_refused_with_the_rule_they_break(name, value, message):
    with pytest.raises(ValueError, match=re.escape(message)) as refused:
        settings_from({name: value})
    assert len(str(refused.value)) < 200  # a 5,000-character value is not repeated in full
    rule = OPTIONS_BY_NAME[name].rule
    assert (
        rule is not None and parameters.descriptor(OPTIONS_BY_NAME[name]).additional_constraints == rule.text
    )
    for fine in (0.0, 1e-6, 0.05) if name == "voxel_size" else ("", "map", "f" * 255, "robot_1/lidar"):
        assert getattr(settings_from({name: fine}), name) == fine


def test_descriptors_carry_descriptions_and_ranges():
    overlap = parameters.descriptor(OPTIONS_BY_NAME["overlap"])
    assert overlap.description and overlap.floating_point_range[0].to_value == 1.0
    levels = parameters.descriptor(OPTIONS_BY_NAME["levels"])
    assert levels.integer_range[0].from_value == 1
    assert "frisicp" in parameters.descriptor(OPTIONS_BY_NAME["method"]).additional_constraints
    assert parameters.descriptor(OPTIONS_BY_NAME["model_qos"]).read_only
    assert parameters.descriptor(OPTIONS_BY_NAME["bag_rate"]).read_only


def test_every_core_option_is_an_option_with_the_core_default():
    nested = {"criteria": ConvergenceCriteria, "tolerance": Tolerance}  # one option per field
    core = {f.name for f in fields(RegistrationConfig)} - set(settings.NOT_OPTIONS) - set(nested)
    core |= {f"{owner}.{f.name}" for owner, kind in nested.items() for f in fields(kind)}
    backed = {o.core for o in settings.OPTIONS if o.core}
    assert core == backed, sorted(core ^ backed)
    # The core's defaults, but for the stream's own budget (a library call runs to its end).
    stream_default = PipelineSettings.create().registration
    assert stream_default == replace(RegistrationConfig(), budget_seconds=settings.STREAM_BUDGET_SECONDS)
    assert RegistrationConfig().budget_seconds is None and settings.STREAM_BUDGET_SECONDS == 15.0
    assert OPTIONS_BY_NAME["backend"].choices == BACKENDS  # the core's list, not a copy


def test_zero_stands_for_the_cores_none_both_ways():
    config = settings.registration_config({"max_distance": 0.0})
    assert config.max_distance is None
    assert settings.algorithm_values(config)["max_distance"] == 0.0
    assert settings.registration_config({"max_distance": 3.0}).max_distance == 3.0


def test_settings_round_trip_through_their_values():
    custom = PipelineSettings.create(dims=2, overlap=0.7, max_iterations=5, initialization="moments")
    assert PipelineSettings.create(**custom.values()) == custom
    assert custom.registration.criteria.max_iterations == 5


def test_every_option_reaches_the_surfaces_it_names():
    from frisicp_ros.cli.main import build_parser

    subcommands = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    for surface, command in ((Surface.BAG, "bag"), (Surface.REGISTER, "register")):
        dests = {action.dest for action in subcommands[command]._actions}
        for option in settings.OPTIONS:
            assert (option.name in dests) == bool(surface & option.surfaces), (command, option.name)
    for option in settings.OPTIONS:
        assert (option.name in parameters.NAMES) == bool(Surface.NODE & option.surfaces), option.name


def test_the_tolerance_is_three_options_and_probing_and_polishing_can_be_switched_off():
    config = settings.registration_config(
        {"tolerance_rotation_deg": 2.5, "tolerance_translation": 0.01, "probe": False, "polish": False}
    )
    assert config.tolerance == Tolerance(rotation_deg=2.5, scale=0.01, translation=0.01)
    assert (config.probe, config.polish) == (False, False)
    assert settings.algorithm_values(config)["tolerance_rotation_deg"] == 2.5
    assert PipelineSettings.create(
        **settings_from({"tolerance_scale": 0.02}).values()
    ).registration.tolerance == (Tolerance(scale=0.02))
    with pytest.raises(ValueError, match=r"tolerance_scale must be in \[1e-06, 1\], got 0.0"):
        settings.registration_config({"tolerance_scale": 0.0})


def test_the_tolerance_and_probe_and_polish_on_the_command_line():
    from frisicp_ros.cli.main import build_parser
    from frisicp_ros.cli.register import config_from_args

    args = build_parser().parse_args(
        ["register", "data.ply", "model.ply", "--tolerance-rotation-deg", "3", "--no-probe", "--no-polish"]
    )
    config = config_from_args(args)
    assert config.tolerance == Tolerance(rotation_deg=3.0)
    assert (config.probe, config.polish) == (False, False)
