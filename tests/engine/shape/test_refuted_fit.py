"""Non-contacts a GPIS fit puts inside observe the outside (``refuted_fit``)."""

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.shape.gpis import fit_gpis
from tactile_viz.engine.shape.gpis_prior import refuted_fit


class _Fit:
    """A fit whose posterior mean is ``values`` at the free points given to the test."""

    def __init__(self, values):
        self.values = np.asarray(values, float)

    def mean_value(self, points):
        return self.values[: len(points)]


def test_rounds_add_the_points_inside_until_none_is_left():
    free = np.arange(12.0).reshape(4, 3)
    fits = iter([_Fit([1.0, -1.0, 1.0, 1.0]), _Fit([1.0, 1.0, 1.0, 1.0])])
    calls = []

    def refit(refuting):
        calls.append(refuting)
        return next(fits)

    fit = refuted_fit(_Fit([-1.0, 1.0, 1.0, 1.0]), free, 0.1, 5, refit)
    np.testing.assert_array_equal(fit.values, [1.0, 1.0, 1.0, 1.0])
    assert len(calls) == 2  # a third round found nothing new inside
    np.testing.assert_array_equal(calls[0], free[[0]])
    np.testing.assert_array_equal(calls[1], free[[0, 1]])  # the first stays observed


def test_no_rounds_no_free_points_or_none_inside_keep_the_fit():
    first = _Fit([-1.0, -1.0])

    def refit(refuting):
        raise AssertionError("no refit expected")

    free = np.zeros((2, 3))
    assert refuted_fit(first, free, 0.1, 0, refit) is first
    assert refuted_fit(first, np.zeros((0, 3)), 0.1, 3, refit) is first
    outside = _Fit([0.5, 0.2])
    assert refuted_fit(outside, free, 0.1, 3, refit) is outside


@pytest.mark.parametrize("size", [1e-3, 1.0, 1e3])
def test_a_miss_where_the_fit_is_inside_ends_outside(size):
    """Contacts on the upper part of a unit ball under a prior ball 1.6 units in radius:
    below, where nothing was touched, the fit closes a surface about a unit below the
    centre; a miss 0.8 units below is inside it, and after the refit it observes the
    outside while the touched surface stays, at any scale."""
    sphere = trimesh.creation.icosphere(2, radius=size)
    upper = sphere.vertices[:, 2] > 0.2 * size
    points, normals = sphere.vertices[upper], sphere.vertex_normals[upper]

    def prior(query):
        query = np.atleast_2d(query)
        length = np.linalg.norm(query, axis=1)
        return length - 1.6 * size, query / length[:, None]

    radius = 8 * size
    fit = fit_gpis(points, normals, prior, radius, noise_variance=1e-4 * size ** 2)
    miss = np.array([[0.0, 0.0, -0.8 * size]])
    value = 0.1 * size
    assert fit.mean_value(miss)[0] < value

    def refit(refuting):
        return fit_gpis(points, normals, prior, radius, scale=fit.scale, newton=False,
                        noise_variance=1e-4 * size ** 2, noncontact_value=value,
                        refuting=refuting)

    refuted = refuted_fit(fit, miss, value, 3, refit)
    assert refuted is not fit
    assert refuted.mean_value(miss)[0] == pytest.approx(value, abs=0.05 * size)
    # The touched surface stays where it was.
    assert np.abs(refuted.mean_value(points)).max() < 0.05 * size


@pytest.mark.parametrize("rounds", [0, 3])
def test_a_session_refutes_only_when_asked(bundled, monkeypatch, rounds):
    """With ``gpis_refute_rounds`` (off by default) a novel session's steps refit with the
    non-contacts their fit put inside; without it, never."""
    from tactile_viz.engine import PriorLibrary, Session, make_truth
    from tactile_viz.engine.session import estimate, session_preset

    assert session_preset("recommended").gpis_refute_rounds == 0
    refuting = []
    monkeypatch.setattr(estimate, "fit_gpis", lambda *args, **kwargs: (
        kwargs.get("refuting") is not None and refuting.append(len(kwargs["refuting"]))
    ) or fit_gpis(*args, **kwargs))
    library = PriorLibrary(bundled[name] for name in ("mug_1", "bottle_1", "vase_1"))
    session = Session.simulated(make_truth(bundled["mug_2"], rng=1), library, "gpis-dhd",
                      params=session_preset("recommended", gpis_refute_rounds=rounds), seed=1)
    session.run(max_steps=30)
    assert any(s.gpis_faces is not None for s in session.snapshots)
    assert (len(refuting) > 0) == (rounds > 0) and all(count > 0 for count in refuting)
