"""The headless engine of tactile_viz: numpy, scipy, trimesh, scikit-image and libigl only.

Nothing here imports Qt, pyvista or vtk; a test enforces it.
"""

from .errors import (LibraryError, MeshError, MeshWarning, ObservationError, ParameterError,
                     TactileVizError)
from .library import PriorLibrary
from .meshes import LONGEST_SIDE, load_mesh, prepare_mesh
from .objects import ModelParams, ObjectModel, bundled_names, load_bundled
from .observations import Contact, NonContact
from .sdf import ExactDistance, SDFGrid, build_sdf_grid
from .simulator import ContactSimulator, GroundTruth
from .transforms import random_pose

__all__ = [
    "Contact", "ContactSimulator", "ExactDistance", "GroundTruth", "LONGEST_SIDE",
    "LibraryError", "MeshError", "MeshWarning", "ModelParams", "NonContact", "ObjectModel",
    "ObservationError", "ParameterError", "PriorLibrary", "SDFGrid", "TactileVizError",
    "build_sdf_grid", "bundled_names", "load_bundled", "load_mesh", "prepare_mesh",
    "random_pose",
]
