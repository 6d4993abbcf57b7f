"""The particle filter's belief: weighted hypotheses and what a step reports.

Both are immutable: a step makes new arrays rather than writing into old ones, so a
checkpoint is a set of references.
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Particles:
    """A weighted set of hypotheses.

    Attributes
    ----------
    classes : (N,) int
        Index of each particle's prior in the library.
    rotations : (N, 3, 3) float
        ``object_to_world`` rotations.
    translations : (N, 3) float
    log_weights : (N,) float
        Normalised: ``logsumexp(log_weights) == 0``.
    """

    classes: np.ndarray
    rotations: np.ndarray
    translations: np.ndarray
    log_weights: np.ndarray

    def __len__(self):
        return len(self.classes)

    def take(self, index):
        return Particles(self.classes[index], self.rotations[index], self.translations[index],
                         self.log_weights[index])

    @staticmethod
    def concatenate(parts):
        return Particles(*(np.concatenate([getattr(p, name) for p in parts])
                           for name in ("classes", "rotations", "translations", "log_weights")))


@dataclass(frozen=True, eq=False)
class FilterState:
    """What a viewer or benchmark reads after a step (immutable).

    Attributes
    ----------
    step : int
    particles : Particles
    class_names : list of str
    class_posterior : dict
        Summed weight per class name.
    map_class : str or None
    map_rotation, map_translation : (3, 3), (3,) float or None
        ``object_to_world`` of the MAP particle.
    log_evidence : float
        ``log p(D | z*)`` over all observations.
    log_threshold : float
        The known/novel threshold on ``log_evidence``: ``n_pos (log 0.9 - log Z)`` for the
        contacts plus ``n_neg log 0.5`` for the non-contacts.
    novel : bool
        True unless the contacts and the non-contacts each reach their part of the
        threshold.
    sampled : int
        Particles added by point-pair sampling in this step.
    n_contacts, n_noncontacts : int
    map_index : int or None
        The MAP's index in ``particles``: the heaviest, unless contending classes were
        told apart by their fit (:mod:`.discrimination`).
    """

    step: int
    particles: Particles
    class_names: list
    class_posterior: dict
    map_class: object
    map_rotation: object
    map_translation: object
    log_evidence: float
    log_threshold: float
    novel: bool
    sampled: int
    n_contacts: int
    n_noncontacts: int
    map_index: object = None

    @property
    def n_particles(self):
        return len(self.particles)
