"""Every parameter is declared once (its field in FilterParams or SessionParams), and what
names parameters elsewhere (the app's knobs, the presets, bench tradeoff's configurations,
the command line) names declared ones."""

from dataclasses import fields

import pytest

from tactile_viz.engine.params import (FilterParams, SessionParams, declaration, declarations,
                                       length_fields, with_changes)
from tactile_viz.engine.presets import PRESETS, SESSION_PRESETS
from tactile_viz.engine.errors import ParameterError


def test_every_field_is_declared_with_its_component_unit_and_doc():
    known = declarations()
    assert set(known) == ({f.name for f in fields(FilterParams)}
                          | {f.name for f in fields(SessionParams)} - {"filter"})
    for name, power in {**length_fields(FilterParams), **length_fields(SessionParams)}.items():
        assert "size unit" in known[name].unit, name
    assert known["sigma_d"].component == "filter" and known["eps"].component == "session"
    assert known["eps"].default == 0.6 and known["eps"].doc.startswith("Termination")
    assert known["merge_angle_deg"].unit == "degrees"
    with pytest.raises(ParameterError, match="unknown parameter"):
        declaration("sigma")


def test_changes_go_to_their_component():
    params = with_changes(SessionParams(), sigma_d=0.7, eps=0.5)
    assert params.filter.sigma_d == 0.7 and params.eps == 0.5


def test_presets_change_only_declared_parameters():
    known = declarations()
    for params in [*PRESETS.values(), *(p.filter for p in SESSION_PRESETS.values())]:
        assert isinstance(params, FilterParams)
    for params in SESSION_PRESETS.values():
        changed = {f.name for f in fields(SessionParams) if f.name != "filter"
                   and getattr(params, f.name) != getattr(SessionParams(), f.name)}
        assert changed <= set(known)


def test_the_apps_knobs_and_the_tradeoff_configurations_are_declared():
    from tactile_viz.app.scene import KNOBS
    from tactile_viz.experiments.tradeoff import CONFIGS

    known = declarations()
    assert set(KNOBS) <= set(known)
    for knob in KNOBS:
        assert known[knob].low is not None and known[knob].high is not None, knob
    for name, (base, session_changes, filter_changes) in CONFIGS.items():
        assert base in SESSION_PRESETS, name
        for changed in {**session_changes, **filter_changes}:
            assert changed in known, (name, changed)
        for changed in session_changes:
            assert known[changed].component == "session", (name, changed)
        for changed in filter_changes:
            assert known[changed].component == "filter", (name, changed)


def test_command_line_parameters_are_declared():
    """Options that set a parameter name it: --outlier-probability sets outlier_probability."""
    from tactile_viz.__main__ import build_parser

    parser = build_parser()
    trial = parser._subparsers._group_actions[0].choices["trial"]
    options = {a.dest for a in trial._actions}
    known = declarations()
    parameter_options = options & set(known)
    # --position-noise is the sensor's noise, which noise_matched gives the filter too.
    assert parameter_options == {"outlier_probability", "position_noise"}
