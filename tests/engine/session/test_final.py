"""The final surface's choice among candidates (``FinalSurface.best_supported``), on a
stand-in estimator: which surfaces it weighs, not how they are fitted."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.session.final import FinalSurface, cell_of
from tactile_viz.engine.session.snapshot import Reconstruction


class _Candidates(FinalSurface):
    """An estimator whose candidates are counted, each supported ``candidate_support``."""

    def __init__(self, eps, candidate_support):
        self.p = SimpleNamespace(eps=eps, final_resolution=64, final_screen_resolution=32,
                                 final_support_open=False, gpis_fill_voids=False)
        self.state = SimpleNamespace(gpis=SimpleNamespace(shape=None))
        self.candidate_support, self.weighed = candidate_support, 0

    def _final_candidates(self, final, contacts, prior):
        for _ in range(3):
            self.weighed += 1
            yield "fit", ((0.0, 0.0, 0.0), (6.4, 1.0, 1.0)), None

    def _level(self, fit, box, resolution, tree):
        return ("vertices", "faces"), self.candidate_support

    def _surface(self, fit, box, resolution, level=None):
        return (SimpleNamespace(chosen=fit, resolution=resolution),)


def _final(reach):
    """A surface on 64 cells of a box 6.4 long (cells of 0.1) whose farthest vertex lies
    ``reach`` from the only contact."""
    vertices = np.array([[0.0, 0.0, 0.0], [reach, 0.0, 0.0]])
    return SimpleNamespace(vertices=vertices, closure=None, resolution=64,
                           bounds=(np.zeros(3), np.array([6.4, 1.0, 1.0])))


@pytest.mark.parametrize("reach, searched", [(1.0, False), (1.05, False), (1.2, True)])
def test_a_final_surface_within_a_cell_of_eps_is_covered(reach, searched):
    # The stop judged the same fit on the exploration's coarser cells: a surface a finer
    # grid moves beyond eps by less than one of its cells (0.1) is covered, and no
    # candidate is fitted (a 10 cm mug's last step: 0.04 mm beyond, seven candidates, 1.5 s).
    estimator = _Candidates(eps=1.0, candidate_support=5.0)
    final = _final(reach)
    chosen, shape = estimator.best_supported(final, np.zeros((1, 3)), prior=None)
    assert (estimator.weighed > 0) == searched
    assert chosen is final and shape is None  # the candidates, weighed, support it worse


@pytest.mark.parametrize("candidate_support, taken", [(1.08, True), (1.15, False)])
def test_a_candidate_within_a_cell_of_eps_is_taken_first(candidate_support, taken):
    estimator = _Candidates(eps=1.0, candidate_support=candidate_support)
    chosen = estimator.best_supported(_final(3.0), np.zeros((1, 3)), prior=None)[0]
    assert chosen.chosen == "fit" and chosen.resolution == 64
    # The first covered one ends the search; otherwise every candidate is weighed.
    assert estimator.weighed == (1 if taken else 3)


def test_the_cell_is_the_longest_side_over_the_resolution():
    assert cell_of(((0.0, 0.0, 0.0), (6.4, 1.0, 2.0)), 64) == pytest.approx(0.1)
    assert cell_of(None, 64) == 0.0


class _Reporting(FinalSurface):
    """An estimator that reports a given surface: its parameters, misses and noise."""

    def __init__(self, noise, refuted, normals):
        self.p = dataclasses.replace(session_preset("recommended"), eps=0.6,
                                     contact_spacing=0.3)
        self.state = SimpleNamespace(refuted=refuted)
        self.filter = SimpleNamespace(contact_normals=normals)
        self.sensor_noise = (noise, 0.0)


@pytest.mark.parametrize("noise, kept", [(0.0, True), (0.01, False), (1.0, True)])
def test_a_blob_within_eps_but_beyond_the_noise_is_not_reported_under_noise(noise, kept):
    # A body touched all over and a blob 0.45 from a shell of contacts, misses about it:
    # within eps (0.6) of a contact, beyond the spacing (0.3). Noiseless, or where the
    # noise explains 0.45 (4 stds of 1.0, at most eps), it is reported; else it is not.
    body = trimesh.creation.icosphere(2, 1.0)
    blob = trimesh.creation.icosphere(1, 0.3)
    blob.apply_translation([3.0, 0.0, 0.0])
    both = trimesh.util.concatenate([body, blob])
    vertices, faces, n = np.asarray(both.vertices), np.asarray(both.faces), len(body.vertices)
    centre = np.array([3.0, 0.0, 0.0])
    contacts = np.vstack([vertices[:n], centre + (vertices[n:] - centre) * 0.75 / 0.3])
    recon = Reconstruction(vertices, faces, np.arange(4), np.zeros(4), fit=None,
                           resolution=32)
    # The contacts face the way of the surface beside them (the body's, the blob's).
    normals = np.vstack([vertices[:n], vertices[n:] - centre])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    estimator = _Reporting(noise, refuted=vertices[n:] + [0.0, 0.1, 0.0], normals=normals)
    reported = estimator.reported(recon, contacts, {})
    assert len(reported.vertices) == (len(vertices) if kept else n)


def test_recent_priors_whose_posed_surfaces_agree_are_weighed_once():
    """A prior of the same class whose posed surface agrees within the tolerance with a
    newer one's (a cylinder turned about its axis, or moved by less) is that one; turned
    off its axis, moved farther, or another class, it is weighed; at 0 only the very
    same pose is."""
    from scipy.spatial.transform import Rotation

    from tactile_viz.engine import ObjectModel, PriorLibrary
    from tactile_viz.engine.belief.particle_filter import ParticleFilter

    meshes = {"cylinder": trimesh.creation.cylinder(radius=1.5, height=6, sections=48),
              "box": trimesh.creation.box(extents=(6, 3, 2))}
    library = PriorLibrary([ObjectModel.from_arrays(m.vertices, m.faces, name)
                            for name, m in meshes.items()])
    estimator = FinalSurface()
    estimator.filter = ParticleFilter(library)
    spin, tip = (Rotation.from_rotvec(v).as_matrix() for v in ([0, 0, 0.9], [0.9, 0, 0]))
    still, near, far = np.zeros(3), np.array([0.03, 0.0, 0.0]), np.array([0.5, 0.0, 0.0])
    recent = [("cylinder", spin, still), ("cylinder", tip, still), ("box", spin, still),
              ("cylinder", np.eye(3), near), ("cylinder", np.eye(3), far),
              ("cylinder", np.eye(3), still)]
    estimator.snapshots = [SimpleNamespace(map_class=c, map_rotation=r, map_translation=t,
                                           novel=True) for c, r, t in reversed(recent)]
    current = ("cylinder", np.eye(3), still)
    weighed = estimator._recent_priors(10, current, tolerance=0.1)
    assert [(c, round(float(np.linalg.norm(t)), 2)) for c, _, t in weighed] == [
        ("cylinder", 0.0), ("cylinder", 0.0), ("box", 0.0), ("cylinder", 0.5)]
    np.testing.assert_allclose(weighed[1][1], tip)
    assert len(estimator._recent_priors(10, current)) == 6  # all but the very same pose
