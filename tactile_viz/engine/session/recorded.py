"""A session that steps through recorded touches."""

from ..errors import SessionError
from .loop import Session


class RecordedSession(Session):
    """A session that steps through recorded touches: :meth:`step` gives the next recorded
    step to :meth:`~Session.observe`, and the session ends with the recording (not at the
    stop rule, which a recording may have passed long before).

    Parameters
    ----------
    steps : list of RecordedStep
        From :func:`~tactile_viz.engine.io.observation_file.read_observations`.
    library, strategy, params, seed
        As for :class:`Session` (the recording's seed reproduces its estimates exactly).
    source : str, optional
        Where the recording came from (shown by viewers).
    scene : Scene, optional
        The robot's world the touches were made in (table contacts become misses; the
        coverage counts what its probe can reach).
    """

    def __init__(self, steps, library, strategy="gpis-dhd", params=None, seed=0, source=None,
                 sensor_noise=(0.0, 0.0), scene=None):
        super().__init__(library, strategy, params, seed, sensor_noise, scene=scene)
        self.recording = list(steps)
        self.source = source

    def setup(self):
        """The constructor's arguments that made this session (see :meth:`Session.setup`)."""
        return {"steps": self.recording, "library": self.library, "strategy": self.strategy,
                "params": self.params, "seed": self.seed, "source": self.source,
                "sensor_noise": self.sensor_noise, "scene": self.scene}

    @property
    def replayed(self):
        """Recorded steps given to the session (misses before the first contact are held)."""
        return self.state.replayed

    @property
    def terminated(self):
        return self.replayed >= len(self.recording)

    def step(self):
        """Replay recorded steps until one gives a snapshot (misses before the first
        contact join its step); at the recording's end without a contact, None."""
        if self.terminated:
            raise SessionError("the recording has been replayed to its end")
        snapshot = None
        while snapshot is None and not self.terminated:
            recorded = self.recording[self.replayed]
            snapshot = self.observe(recorded.observations, recorded.free_space)
            self.state.replayed += 1
        if snapshot is None:
            raise SessionError("the recording holds no contact: there is nothing to "
                               "estimate from misses alone")
        return snapshot
