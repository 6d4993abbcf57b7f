"""Learning a shape: a novel object's reconstruction as a new prior (paper, shape transfer
learning)."""

import trimesh

from ..errors import SessionError
from ..shape.gpis import ThinPlateKernel, zero_level_surface
from ..shape.gpis_variance import lattice_low
from ..shape.objects import ObjectModel


class Learning:
    """The learned model of a session's snapshot (a mixin of :class:`~.loop.Session`)."""

    def learned_model(self, name, snapshot=None, resolution=None):
        """The reconstructed surface of a novel snapshot as a new :class:`ObjectModel`.

        The snapshot's GPIS posterior mean (its contacts, MAP prior and kernel scale) is
        extracted at ``resolution`` (default ``params.learned_resolution``; a stopped
        session's last surface is already at ``params.final_resolution``); the
        largest connected piece of the zero level set is kept, and the model is checked and
        normalised like any loaded mesh.
        """
        snapshot = snapshot or self.latest
        if snapshot is None or snapshot.gpis_faces is None or len(snapshot.gpis_faces) == 0:
            raise SessionError("no reconstructed surface to learn from: the object was not "
                               "judged novel in this step")
        resolution = resolution or self._p.learned_resolution
        vertices, faces = snapshot.gpis_vertices, snapshot.gpis_faces
        if resolution != snapshot.gpis_resolution:
            vertices, faces = self._surface_at(snapshot, resolution)
        return learned_model_from_surface(vertices, faces, name,
                                          params=self.library[snapshot.map_class].params
                                          if snapshot.map_class in self.library else None)

    def _surface_at(self, snapshot, resolution):
        """The snapshot's GPIS zero level set on a grid of ``resolution`` cells, fitted with
        the snapshot's MAP prior (a stopped session may report the surface of a recent
        prior instead, ``final_candidates``; it is learned as reported at
        ``final_resolution``, the default ``learned_resolution``)."""
        model = self.filter.models[self.filter.class_names.index(snapshot.map_class)]
        self._use_lengths(model)
        prior = self._gpis_prior(model, snapshot.map_rotation, snapshot.map_translation,
                                 snapshot.contacts, snapshot.noncontacts, snapshot.free_space)
        low, high, kernel = self._gpis_box(snapshot.map_vertices, snapshot.contacts)
        if isinstance(kernel, ThinPlateKernel) and snapshot.gpis_radius is not None:
            kernel = ThinPlateKernel(snapshot.gpis_radius)  # the step's, maybe kept
        spacing = snapshot.gpis_spacing if resolution == snapshot.gpis_resolution else None
        if spacing is not None:
            low = lattice_low(low, spacing)
        fit = self._refit(kernel, snapshot.contacts, snapshot.normals,
                          self._noncontact_points(snapshot.noncontacts, snapshot.free_space),
                          prior, snapshot.gpis_scale)
        fit = self._cut_estimate(fit, snapshot.contacts, snapshot.noncontacts,
                                 snapshot.free_space)
        vertices, faces = zero_level_surface(fit, (low, high), resolution, spacing=spacing)
        if len(faces) == 0:
            raise SessionError("the reconstruction has no surface at the learned resolution")
        return vertices, faces


def learned_model_from_surface(vertices, faces, name, params=None):
    """An :class:`ObjectModel` from a reconstructed surface (largest connected piece).

    The surface keeps its measured size: it is in the same world units as the object it was
    learned from, whereas scaling its (pose-dependent) bounding box to the bundled objects'
    size would change its size and spoil every later match.
    """
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    pieces = mesh.split(only_watertight=False)
    if len(pieces):
        mesh = max(pieces, key=lambda piece: abs(piece.area))
    return ObjectModel.from_arrays(mesh.vertices, mesh.faces, name, params=params,
                                   longest_side=None, learned=True)
