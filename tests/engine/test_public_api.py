"""What the README's examples import: the engine's public names, from one place."""

import tactile_viz.engine as engine


def test_engine_exports_the_session_api():
    from tactile_viz.engine import (
        FilterParams,
        ParticleFilter,
        Session,
        SessionParams,
        Snapshot,
        preset,
        session_preset,
    )
    from tactile_viz.engine.params import FilterParams as FilterParamsAgain
    from tactile_viz.engine.session import Session as SessionAgain

    assert Session is SessionAgain and FilterParams is FilterParamsAgain
    assert isinstance(session_preset("recommended"), SessionParams)
    assert isinstance(preset("paper"), FilterParams)
    assert ParticleFilter.__module__.endswith("particle_filter") and Snapshot


def test_all_names_exist():
    missing = [name for name in engine.__all__ if not hasattr(engine, name)]
    assert missing == []
    assert len(set(engine.__all__)) == len(engine.__all__)


def test_the_public_api_is_typed():
    import typing

    from tactile_viz.engine import (
        ObjectModel,
        PriorLibrary,
        Session,
        load_bundled,
        read_observations,
        session_preset,
    )

    for function in (Session.__init__, Session.step, Session.propose, Session.observe,
                     Session.run, PriorLibrary.save, PriorLibrary.load, ObjectModel.from_file,
                     load_bundled, read_observations, session_preset):
        hints = typing.get_type_hints(function)
        assert "return" in hints, function.__qualname__
