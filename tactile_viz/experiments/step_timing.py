"""Benchmark: time of each part of a step at 50, 200 and 400 contacts.

``python -m tactile_viz bench step [--object mug_2] [--sizes 50 200 400] [--repeats 5]``

Contacts are sampled on the object at a random pose and fed to the particle filter; then
each part of one more step (filter update, GPIS fit, surface extraction with variance,
target choice, simulator probe, the decision beyond the paper: a full search, and a touch
between full searches that starts from a full search's hypotheses at the same contacts)
is timed ``--repeats`` times
and the median printed, beside a reference of the machine's speed: the Cholesky factor of
an 800 x 800 matrix ``a a^T + 800 I``. The
GPIS factorisation is also timed both ways: a full Cholesky of ``a K0 + s I`` against
appending the new contact's 4 rows to the previous factor (block update, O(n^2)); and the
``recommended`` preset's incremental fit and surface (docs/gpis.md) when that contact joins.
"""

import argparse
import functools
import time
from dataclasses import replace

import numpy as np
from scipy.linalg import cholesky, solve_triangular

from ..cli import ArgumentParser, ExtendList, bundled_object, count_int, seed_int
from ..engine.belief.decision import decide
from ..engine.belief.particle_filter import ParticleFilter
from ..engine.explore.exploration import enforce_contact
from ..engine.explore.simulator import ContactSimulator, random_touch
from ..engine.session import make_truth, session_preset
from ..engine.shape.gpis import (
    ThinPlateKernel,
    WendlandKernel,
    fit_gpis,
    kernel_blocks,
    stable_cholesky,
)
from ..engine.shape.gpis_incremental import fit_gpis_incremental
from ..engine.shape.gpis_variance import lattice_low, lattice_variance
from ..engine.shape.level_set import zero_level_surface
from ..engine.shape.library import PriorLibrary
from ..engine.shape.objects import load_bundled


def _median_time(function, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def append_factor(factor, cross, corner):
    """Cholesky factor of ``[[A, B], [B^T, C]]`` from the factor of ``A``: O(n^2 k)."""
    lower_left = solve_triangular(factor, cross, lower=True, check_finite=False).T
    lower_right = cholesky(corner - lower_left @ lower_left.T, lower=True, check_finite=False)
    n, k = len(factor), len(corner)
    result = np.zeros((n + k, n + k))
    result[:n, :n] = factor
    result[n:, :n] = lower_left
    result[n:, n:] = lower_right
    return result


def measure(object_name, sizes, repeats, seed=0):
    library = PriorLibrary.bundled("known")
    truth = make_truth(load_bundled(object_name), rng=seed)
    simulator = ContactSimulator(truth)
    rng = np.random.default_rng(seed)
    rows = []
    particle_filter = ParticleFilter(library, rng=seed)
    square = np.random.default_rng(seed).standard_normal((800, 800))  # the reference's
    p = session_preset("recommended")
    for size in sizes:
        while len(particle_filter.contact_positions) < size:
            particle_filter.update(simulator.probe(random_touch(truth, rng)))
        state = particle_filter.state
        model = particle_filter.models[particle_filter.class_names.index(state.map_class)]
        rotation, translation = state.map_rotation, state.map_translation
        contacts, normals = particle_filter.contact_positions, particle_filter.contact_normals
        low, high = contacts.min(axis=0) - 1.0, contacts.max(axis=0) + 1.0
        radius = _paper_kernel(low, high)

        def prior(points):
            values, gradients = model.sdf.evaluate((points - translation) @ rotation)
            return values, gradients @ rotation.T

        path = random_touch(truth, rng)
        observation = simulator.probe(path)
        timing = {}
        timing["filter"] = _median_time(lambda: _copy_update(particle_filter, observation), repeats)
        fit = fit_gpis(contacts, normals, prior, radius)
        timing["gpis fit"] = _median_time(lambda: fit_gpis(contacts, normals, prior, radius,
                                                           scale=fit.scale), repeats)
        vertices = zero_level_surface(fit, (low, high), 32)[0]
        subset = vertices[rng.choice(len(vertices), min(1500, len(vertices)), replace=False)]
        timing["surface"] = _median_time(
            lambda: (zero_level_surface(fit, (low, high), 32), fit.variance(subset)), repeats)
        timing["target"] = _median_time(
            lambda: (np.argmax(fit.variance(subset[:1])), fit.mean(subset[:1])), repeats)
        timing["decision"] = _median_time(lambda: _decision(particle_filter, p), repeats)
        searched = _decision(particle_filter, p, refresh=p.decision_refresh)
        timing["decision between searches"] = _median_time(lambda: _decision(
            particle_filter, p, refresh=p.decision_refresh, carried=searched.carried,
            refined=replace(searched.refined, decided=False)), repeats)
        timing["simulator"] = _median_time(
            lambda: enforce_contact(simulator, path[0] * 0.5 + path[1] * 0.5,
                                    np.array([0.0, 0.0, 1.0]), contacts, normals), repeats)
        noise = 1e-4
        gram = fit.scale * kernel_blocks(contacts, contacts, radius) + noise * np.eye(4 * size)
        previous = stable_cholesky(gram[:-4, :-4])[0]
        timing["cholesky full"] = _median_time(lambda: stable_cholesky(gram), repeats)
        timing["cholesky append"] = _median_time(
            lambda: append_factor(previous, gram[:-4, -4:], gram[-4:, -4:]), repeats)
        timing.update(_incremental(contacts, normals, prior, radius, fit.scale, (low, high),
                                   repeats))
        timing["reference"] = _median_time(lambda: reference_cholesky(square), repeats)
        rows.append((size, timing))
    return rows


def reference_cholesky(a):
    """The machine's speed: the Cholesky factor of ``a a^T + n I`` for a square ``a (n, n)``
    (standard normal, n = 800: the reference the decision's cost is compared with)."""
    return cholesky(a @ a.T + len(a) * np.eye(len(a)), lower=True, check_finite=False)


def _decision(particle_filter, p, **options):
    """The decision of the filter's belief with the session parameters ``p`` (the bundled
    objects' size unit is one scene unit): a full search, or with ``options``
    (``refresh``, ``carried``, ``refined``) a touch between full searches."""
    return decide(particle_filter, particle_filter.state, p.decision_confidence,
                  floor=p.decision_floor, same_mode=p.decision_same_mode,
                  pose_tolerance=p.decision_pose_error, normals=p.decision_normals,
                  least_turn_p=p.decision_normals_p, **options)


def _incremental(contacts, normals, prior, kernel, scale, box, repeats):
    """The fit and the surface of the ``recommended`` preset's incremental path when the
    last contact joins (``gpis_incremental``): the factor and the lattice variances of the
    others extended, no Newton step."""
    fast = functools.partial(fit_gpis_incremental, prior=prior, kernel=kernel, scale=scale,
                             refit=False, refit_score=np.inf)
    before, cache, _ = fast(contacts[:-1], normals[:-1], cache=None)
    after = fast(contacts, normals, cache=cache)[0]
    spacing = float(np.ptp(np.asarray(box), axis=0).max()) / 32
    low = lattice_low(box[0], spacing)

    def surface(fit, nodes=None):
        vertices = zero_level_surface(fit, (low, box[1]), 32, spacing=spacing)[0]
        return lattice_variance(fit, vertices, low, spacing, nodes)[1]

    nodes = surface(before)
    return {"gpis fit incremental": _median_time(lambda: fast(contacts, normals, cache=cache),
                                                 repeats),
            "surface incremental": _median_time(lambda: surface(after, nodes), repeats)}


def _paper_kernel(low, high):
    """The GPIS kernel of the ``paper`` preset for a reconstruction box."""
    params = session_preset("recommended")
    if params.gpis_kernel == "wendland":
        return WendlandKernel(params.gpis_support)
    return ThinPlateKernel(params.gpis_radius_factor * float(np.linalg.norm(high - low)))


def _copy_update(particle_filter, observation):
    """Time an update without changing the filter: restore its state afterwards."""
    saved = (particle_filter.particles, particle_filter.contact_positions,
             particle_filter.contact_normals, particle_filter.noncontact_positions,
             particle_filter.step_count, particle_filter.state)
    try:
        particle_filter.update(observation)
    finally:
        (particle_filter.particles, particle_filter.contact_positions,
         particle_filter.contact_normals, particle_filter.noncontact_positions,
         particle_filter.step_count, particle_filter.state) = saved


def main(argv=None):
    parser = ArgumentParser(prog="python -m tactile_viz bench step", description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="mug_2", type=bundled_object())
    parser.add_argument("--sizes", type=count_int, action=ExtendList, default=[50, 200, 400])
    parser.add_argument("--repeats", type=count_int, default=5)
    parser.add_argument("--seed", type=seed_int, default=0)
    args = parser.parse_args(argv)
    rows = measure(args.object, args.sizes, args.repeats, args.seed)
    names = list(rows[0][1])
    print(f"median seconds per part of a step ({args.object}, {args.repeats} repeats)")
    print("| contacts | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 1) + "|")
    for size, timing in rows:
        print(f"| {size} | " + " | ".join(f"{timing[name]:.4f}" for name in names) + " |")
    return 0
