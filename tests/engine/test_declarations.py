"""Every parameter is declared once (its field in FilterParams or SessionParams, made by
param_schema.param), its validation comes from there, and what names parameters elsewhere
(the app's knobs, the presets, bench tradeoff's configurations, the command line) names
declared ones with values in their ranges."""

import math
import subprocess
import sys
from dataclasses import fields

import pytest

from tactile_viz.engine.errors import ParameterError
from tactile_viz.engine.param_schema import Interval
from tactile_viz.engine.params import (
    FilterParams,
    SessionParams,
    declaration,
    declarations,
    length_fields,
    with_changes,
)
from tactile_viz.engine.presets import PRESET_TABLE, PRESETS, SESSION_PRESETS


def test_every_field_is_declared_with_its_component_unit_and_doc():
    known = declarations()
    assert set(known) == ({f.name for f in fields(FilterParams)}
                          | {f.name for f in fields(SessionParams)} - {"filter"})
    for name, power in {**length_fields(FilterParams), **length_fields(SessionParams)}.items():
        assert "size unit" in known[name].unit and known[name].length == power, name
    assert {d.component for d in known.values()} == {"filter", "session", "gpis"}
    assert all(known[f.name].component == "filter" for f in fields(FilterParams))
    assert known["eps"].default == 0.6 and known["eps"].doc.startswith("Termination")
    assert known["merge_angle_deg"].unit == "degrees"
    for name, item in known.items():
        assert item.doc.endswith((".", "...")) and "\n" not in item.doc, name
        assert item.doc in (FilterParams.__doc__ + SessionParams.__doc__).replace(
            "\n        ", " "), name
        if item.kind in ("int", "float", "optional-float"):
            assert isinstance(item.valid, Interval), name
    with pytest.raises(ParameterError, match="unknown parameter"):
        declaration("sigma")


def test_validation_names_the_parameter_the_value_and_the_range():
    with pytest.raises(ParameterError, match=r"outlier_probability must lie in \[0, 0\.5\), "
                                             r"got 0\.5"):
        FilterParams(outlier_probability=0.5)
    with pytest.raises(ParameterError, match=r"eps must lie in \(0, inf\), got -1"):
        SessionParams(eps=-1)
    with pytest.raises(ParameterError, match=r"n_s must be an integer, got 2\.5"):
        declaration("n_s").check(2.5)
    assert declaration("n_s").check(30.0) == 30 and FilterParams(n_s=30.0).n_s == 30
    assert SessionParams(length_unit=2).length_unit == 2.0
    with pytest.raises(ParameterError, match="gpis_kernel must be one of"):
        SessionParams(gpis_kernel="rbf")
    with pytest.raises(ParameterError, match="must be True or False"):
        SessionParams(cover_prior=1)


def test_changes_go_to_their_component():
    params = with_changes(SessionParams(), sigma_d=0.7, eps=0.5, gpis_support=3.0)
    assert params.filter.sigma_d == 0.7 and params.eps == 0.5 and params.gpis_support == 3.0
    with pytest.raises(ParameterError, match="unknown parameter"):
        with_changes(SessionParams(), epsilon=0.5)


@pytest.mark.parametrize("name", sorted(PRESET_TABLE))
def test_a_preset_names_declared_parameters_with_values_in_their_ranges(name):
    for parameter, value in PRESET_TABLE[name].items():
        assert parameter in declarations(), (name, parameter)
        declaration(parameter).check(value)  # raises for a value out of its range
    params = SESSION_PRESETS[name]
    changed = {f.name for f in fields(SessionParams) if f.name != "filter"
               and getattr(params, f.name) != getattr(SessionParams(), f.name)}
    changed |= {f.name for f in fields(FilterParams)
                if getattr(params.filter, f.name) != getattr(FilterParams(), f.name)}
    assert changed <= set(PRESET_TABLE[name]), name  # nothing beside its row
    if name in PRESETS:  # the filter preset: changes from its row only
        for item in fields(FilterParams):
            value = getattr(PRESETS[name], item.name)
            if value != getattr(FilterParams(), item.name):
                assert PRESET_TABLE[name][item.name] == value, (name, item.name)


def test_presets_keep_their_values():
    assert PRESETS["paper"] == FilterParams(contenders=0, sdf_max_resolution=0,
                                            learned_noise=False)
    assert SESSION_PRESETS["recommended"] == SessionParams()
    assert SESSION_PRESETS["paper"].filter == FilterParams(contenders=0, refine_learned=0,
                                                           sdf_max_resolution=0,
                                                           learned_noise=False)
    assert SESSION_PRESETS["recognise"].filter.sdf_exact_band == 4.0
    assert SESSION_PRESETS["fast"].filter == PRESETS["fast"]
    assert SESSION_PRESETS["accurate"].gpis_resolution == 48


def test_the_apps_knobs_are_declared_with_a_range_a_control_can_offer():
    from tactile_viz.app.scene import KNOBS
    from tactile_viz.gui.panels.exploration_panel import PARAMETERS

    assert PARAMETERS is KNOBS  # one list of them
    for knob in KNOBS:
        item = declaration(knob)
        assert item.low is not None and item.high is not None, knob
        assert item.low in item.valid and item.high in item.valid, knob
        assert math.isfinite(item.default) and item.default in item.valid, knob


def test_the_tradeoff_configurations_name_declared_parameters_in_range():
    from tactile_viz.experiments.tradeoff import CONFIGS

    for name, (base, changes) in CONFIGS.items():
        assert base in SESSION_PRESETS, name
        for parameter, value in changes.items():
            declaration(parameter).check(value)


def test_command_line_parameter_options_are_declared():
    """Options that set a parameter are --set and those of cli.PARAMETER_OPTIONS, whose
    parameters are declared; no other option of trial or replay is named after one."""
    from tactile_viz.__main__ import build_parser
    from tactile_viz.cli import PARAMETER_OPTIONS

    assert set(PARAMETER_OPTIONS.values()) <= set(declarations())
    commands = build_parser()._subparsers._group_actions[0].choices
    for command in ("trial", "replay"):
        actions = commands[command]._actions
        flags = {flag for action in actions for flag in action.option_strings}
        assert "--set" in flags and set(PARAMETER_OPTIONS) <= flags, command
        named = {flag for action in actions for flag in action.option_strings
                 if action.dest in declarations()}
        # --position-noise is the sensor's noise, which noise_matched gives the filter too.
        assert named - {"--position-noise"} <= set(PARAMETER_OPTIONS), (command, named)


@pytest.mark.parametrize("setting, fault", [
    ("epsilon=0.4", "unknown parameter 'epsilon'"), ("eps=-1", "eps must lie in (0, inf)"),
    ("n_s=2.5", "n_s must be an integer"), ("eps", "expected NAME=VALUE"),
])
def test_a_bad_setting_is_one_line_and_exit_2(setting, fault):
    done = subprocess.run([sys.executable, "-m", "tactile_viz", "trial", "--object", "mug_1",
                           "--set", setting], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and fault in done.stderr
    assert done.stderr.count("\n") == 1, done.stderr


def test_settings_parse_json_words_and_text():
    from tactile_viz.cli import parameter_setting, with_settings

    pairs = [parameter_setting(text) for text in
             ("eps=0.4", "refine_map=true", "stop_at_decision=True", "length_unit=null",
              "check_line_aim=contact", " n_s = 20")]
    params = with_settings(SessionParams(), pairs)
    assert params.eps == 0.4 and params.filter.refine_map and params.stop_at_decision
    assert params.length_unit is None and params.check_line_aim == "contact"
    assert params.filter.n_s == 20
