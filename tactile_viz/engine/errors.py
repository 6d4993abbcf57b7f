"""The project's own exception types.

Every error a user can cause (a broken mesh file, a corrupt library folder, a bad
observation) is raised as one of these, with the offending input and the reason in the
message, so callers can catch :class:`TactileVizError` and show it.
"""


class TactileVizError(Exception):
    """Base class of every error tactile_viz raises on purpose."""


class MeshError(TactileVizError, ValueError):
    """A mesh could not be loaded or is unusable as an object model.

    Parameters
    ----------
    source : str
        The file name (or a description such as ``"arrays"``) the mesh came from.
    reason : str
        What is wrong with it.
    """

    def __init__(self, source, reason):
        self.source = str(source)
        self.reason = reason
        super().__init__(f"{self.source}: {reason}")


class LibraryError(TactileVizError):
    """A prior library folder is missing, corrupt or cannot be written."""


class ObservationError(TactileVizError, ValueError):
    """An observation (contact or non-contact) has the wrong shape or non-finite values."""


class ParameterError(TactileVizError, ValueError):
    """A parameter value is out of range or of the wrong type (named in the message)."""


class BagWarning(UserWarning):
    """A bag read with a guess the user should know of (a topic chosen for them)."""


class MeshWarning(UserWarning):
    """A mesh was changed on loading in a way the user should know about (e.g. decimated)."""


class SessionError(TactileVizError):
    """A session cannot be run, saved or loaded as asked."""
