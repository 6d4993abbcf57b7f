"""The headless engine of tactile_viz: numpy, scipy, trimesh, scikit-image and libigl only.

Everything a script needs is importable from here::

    from tactile_viz.engine import PriorLibrary, Session, load_bundled, make_truth

Nothing here imports Qt, pyvista or vtk; a test enforces it.
"""

from .belief.particle_filter import ParticleFilter
from .errors import (
    LibraryError,
    MeshError,
    MeshWarning,
    ObservationError,
    ParameterError,
    TactileVizError,
)
from .explore.exploration import STRATEGIES
from .explore.observations import Contact, NonContact
from .explore.simulator import ContactSimulator, GroundTruth
from .io.export import export_session
from .io.observation_file import (
    ObservationFileError,
    RecordedStep,
    read_observations,
    write_observations,
)
from .params import FilterParams
from .presets import preset
from .session import (
    SESSION_PRESETS,
    Move,
    Reconstruction,
    RecordedSession,
    Session,
    SessionError,
    SessionParams,
    Snapshot,
    make_truth,
    session_preset,
)
from .session.context import Sensor
from .shape.library import PriorLibrary
from .shape.meshes import LONGEST_SIDE, load_mesh, prepare_mesh
from .shape.objects import ModelParams, ObjectModel, bundled_names, load_bundled
from .shape.sdf import ExactDistance, SDFGrid
from .shape.sdf_build import build_sdf_grid
from .transforms import random_pose

__all__ = [
    "Contact", "ContactSimulator", "ExactDistance", "FilterParams", "GroundTruth",
    "LONGEST_SIDE", "LibraryError", "MeshError", "MeshWarning", "ModelParams", "Move",
    "NonContact", "ObjectModel", "ObservationError", "ObservationFileError", "ParameterError",
    "ParticleFilter", "PriorLibrary", "Reconstruction", "RecordedSession", "RecordedStep",
    "SDFGrid", "SESSION_PRESETS", "STRATEGIES", "Sensor", "Session", "SessionError",
    "SessionParams", "Snapshot",
    "TactileVizError", "build_sdf_grid", "bundled_names", "export_session",
    "load_bundled", "load_mesh", "make_truth", "prepare_mesh", "preset", "random_pose",
    "read_observations", "session_preset", "write_observations",
]
