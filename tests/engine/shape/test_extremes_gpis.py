"""The GPIS at the extremes: noise variance 1e-12 to 1, kernel scale 1e-8 to 1e8, one to
1,000 contacts, duplicate and contradictory contacts, contacts on a plane or a line and far
from the prior's grid. The posterior mean, its gradient and the variance must stay finite,
the variance non-negative and no larger than the prior's, and the fit must honour the data
as far as the noise allows.
"""

import numpy as np
import pytest

from tactile_viz.engine.shape.gpis import fit_gpis
from tactile_viz.engine.shape.level_set import zero_level_surface
from tactile_viz.engine.shape.metrics import surface_samples

NOISES = [1e-12, 1e-8, 1e-4, 1e-2, 1.0]
SCALES = [1e-8, 1e-4, 1.0, 1e4, 1e8]
RADIUS = 15.0


@pytest.fixture(scope="module")
def mug(bundled):
    """1,000 contacts on mug_2 with true normals; mug_1's SDF as the prior mean."""
    truth, prior_model = bundled["mug_2"], bundled["mug_1"]
    _, points, faces = truth.exact.query(surface_samples(truth, 1000, seed=3))
    normals = truth.exact.surface_normal(points, faces)
    return points, normals, (lambda p: prior_model.sdf.evaluate(p)), prior_model


def _assert_sound(fit, query):
    """Finite mean, gradient and variance; 0 <= variance <= prior variance."""
    values, gradients = fit.mean(query)
    variance = fit.variance(query)
    assert np.all(np.isfinite(values)) and np.all(np.isfinite(gradients))
    assert np.all(np.isfinite(variance)) and np.all(variance >= 0)
    assert np.all(variance <= fit.prior_variance * (1 + 1e-9))
    assert np.isfinite(fit.log_marginal_likelihood)
    assert np.isfinite(fit.scale) and fit.scale > 0
    assert np.all(np.isfinite(fit.alpha))
    return values, gradients, variance


@pytest.mark.parametrize("noise", NOISES)
@pytest.mark.parametrize("scale", SCALES)
def test_noise_variance_and_kernel_scale_extremes(mug, noise, scale):
    points, normals, prior, _ = mug
    points, normals = points[:60], normals[:60]
    fit = fit_gpis(points, normals, prior, RADIUS, scale=scale, noise_variance=noise)
    _assert_sound(fit, points + 0.3)
    # One bounded Newton step on log a: never more than a factor e^2.
    assert np.exp(-2) * scale * (1 - 1e-9) <= fit.scale <= np.exp(2) * scale * (1 + 1e-9)
    prior_variance = fit.prior_variance
    at_contacts = fit.variance(points)
    assert np.all(at_contacts <= 1.01 * noise + 1e-8 * prior_variance)
    if noise <= 1e-4 and fit.scale >= 0.1:
        # Data much more certain than the prior: the mean interpolates the contacts.
        values, gradients = fit.mean(points)
        assert np.abs(values).max() < 0.01
        assert np.abs(gradients - normals).max() < 0.05


@pytest.mark.parametrize("count", [1, 2])
def test_one_and_two_contacts(mug, count):
    points, normals, prior, prior_model = mug
    fit = fit_gpis(points[:count], normals[:count], prior, RADIUS)
    values, _, variance = _assert_sound(fit, points[:count] + 0.5)
    assert np.abs(fit.mean_value(points[:count])).max() < 0.01
    # The surface is still the prior's shape, bent through the contact(s).
    bounds = prior_model.mesh.bounds + [[-0.6] * 3, [0.6] * 3]
    vertices, faces = zero_level_surface(fit, bounds, resolution=16)
    assert len(faces) > 50 and np.all(np.isfinite(vertices))


@pytest.mark.slow
def test_a_thousand_contacts(mug):
    """4,000 rows in the Gram matrix (about 6 s on one thread)."""
    points, normals, prior, _ = mug
    fit = fit_gpis(points, normals, prior, RADIUS)
    _, _, variance = _assert_sound(fit, points[:200] + 0.2)
    values, gradients = fit.mean(points[::10])
    assert np.abs(values).max() < 0.02
    assert np.median(np.abs(gradients - normals[::10])) < 0.05
    assert fit.variance(points[::10]).max() < 1e-3


@pytest.mark.parametrize("noise", [1e-12, 1e-4])
@pytest.mark.parametrize("offset", [0.0, 1e-12, 1e-9, 1e-6])
def test_duplicate_and_near_duplicate_contacts(mug, noise, offset):
    """Each of 20 contacts observed three times (the Gram matrix is singular up to the
    noise): the fit is the same as with one copy each."""
    points, normals, prior, _ = mug
    base, base_normals = points[:20], normals[:20]
    copies = np.vstack([base, base + offset, base - offset])
    fit = fit_gpis(copies, np.vstack([base_normals] * 3), prior, RADIUS, noise_variance=noise,
                   newton=False)
    single = fit_gpis(base, base_normals, prior, RADIUS, noise_variance=noise, newton=False)
    query = points[20:80]
    _assert_sound(fit, query)
    np.testing.assert_allclose(fit.mean_value(query), single.mean_value(query), atol=0.01)
    assert np.abs(fit.mean_value(base)).max() < 0.01


@pytest.mark.parametrize("noise", [1e-12, 1e-4])
def test_contradictory_normals_at_one_point(mug, noise):
    """The same point touched with opposite normals (antiparallel, zero distance): no
    solution interpolates both; the fit must stay finite and split the difference."""
    points, normals, prior, _ = mug
    points = np.vstack([points[:10], points[:1]])
    normals = np.vstack([normals[:10], -normals[:1]])
    fit = fit_gpis(points, normals, prior, RADIUS, noise_variance=noise)
    _assert_sound(fit, points + 0.1)
    _, gradient = fit.mean(points[:1])
    assert np.linalg.norm(gradient) < 0.5  # the two normals cancel


@pytest.mark.parametrize("layout", ["plane", "line"])
@pytest.mark.parametrize("noise", [1e-12, 1e-4])
def test_contacts_on_a_plane_or_a_line(mug, layout, noise):
    _, _, prior, _ = mug
    rng = np.random.default_rng(0)
    if layout == "plane":
        points = np.column_stack([rng.uniform(-2, 2, (40, 2)), np.full(40, 1.0)])
    else:
        points = np.column_stack([np.linspace(-2, 2, 40), np.zeros(40), np.full(40, 1.0)])
    normals = np.tile([0, 0, 1.0], (40, 1))
    for scale in (1e-8, 1.0, 1e8):
        fit = fit_gpis(points, normals, prior, RADIUS, scale=scale, noise_variance=noise)
        _assert_sound(fit, points + [0.3, 0.2, 0.5])
    fit = fit_gpis(points, normals, prior, RADIUS, noise_variance=noise)
    values, gradients = fit.mean(points)
    assert np.abs(values).max() < 0.02
    assert np.abs(gradients - normals).max() < 0.05


def test_contacts_far_outside_the_prior_grid(mug):
    """Contacts 1,000 units away, where the prior mean is the grid's fallback: the kernel
    radius grows with the box as in a session, and the fit still interpolates them."""
    points, normals, prior, _ = mug
    far = points[:20] + 1000.0
    radius = 1.2 * np.linalg.norm(np.ptp(np.vstack([far, points[:20]]), axis=0))
    fit = fit_gpis(far, normals[:20], prior, radius)
    _assert_sound(fit, far + 0.5)
    assert np.abs(fit.mean_value(far)).max() < 0.01
    bounds = (far.min(axis=0) - 0.6, far.max(axis=0) + 0.6)
    vertices, faces = zero_level_surface(fit, bounds, resolution=12)
    assert np.all(np.isfinite(vertices))
