"""The state the desktop app shows and steers, without Qt.

A :class:`Scene` holds the user's choices (ground truth object and pose, which priors the
filter uses, strategy, preset and parameter overrides) and the current :class:`Session`.
Views subscribe to its :class:`Signal` s; every change that makes the running session
stale resets it. Bad input (a broken mesh, an unreadable library, an invalid parameter)
raises the project's error and changes nothing.

The scene is the one source of truth of a view: a view shows what the scene holds (its
controls are filled from it after every change, whatever made the change: the command line,
a loaded session, a preset) and never keeps settings of its own. Each session gets a new
:attr:`Scene.generation`, so a view that steps a session in another thread can drop the
snapshots of a session that is no longer current.
"""

import logging
from pathlib import Path
from typing import NamedTuple

from ..engine.errors import LibraryError
from ..engine.explore.exploration import STRATEGIES
from ..engine.io.bags import read_recording, recording_file_warning
from ..engine.io.export import export_session
from ..engine.params import PAPER_SIZE, declaration, declarations, with_changes
from ..engine.scene import FREE, Scene as RobotScene
from ..engine.session import (
    SESSION_PRESETS,
    RecordedSession,
    Session,
    SessionError,
    make_truth,
    session_preset,
)
from ..engine.shape.library import PriorLibrary, size_warning
from ..engine.shape.meshes import UNITS
from ..engine.shape.metrics import error_threshold
from ..engine.shape.objects import ObjectModel, bundled_names, load_bundled

log = logging.getLogger(__name__)

class Knob(NamedTuple):
    """How the window shows a main parameter: ``label``, a spin box's ``step`` and
    ``decimals`` (0: an integer box). Its range, default, unit and doc come from its
    declaration (:func:`tactile_viz.engine.params.declarations`)."""

    label: str
    step: float
    decimals: int


# The main parameters the window offers, in the order it shows them: the one list of them.
KNOBS = {
    "sigma_d": Knob("sigma_d", 0.05, 3),
    "sigma_n": Knob("sigma_n", 0.1, 3),
    "eps": Knob("eps (DHD)", 0.05, 2),
    "n_s": Knob("n_s", 1, 0),
    "lam": Knob("lambda", 0.01, 2),
    "outlier_probability": Knob("outliers", 0.01, 3),
}
# Which dataclass each belongs to comes from its declaration (engine.params.declarations).
FILTER_KNOBS = tuple(name for name in KNOBS if declarations()[name].component == "filter")
SESSION_KNOBS = tuple(name for name in KNOBS if declarations()[name].component == "session")
LOADED_PRESET = "loaded session"  # the base parameters of a loaded session that match no preset
SCENE_UNITS = "scene units"  # the name of the scene's length unit when it has none


def knob_length_power(name):
    """The power of length of a main knob's unit (0: not a length), from the parameters'
    field metadata: 1 for ``sigma_d`` and ``eps``, which are in size units."""
    if name not in KNOBS:
        raise ValueError(f"unknown parameter {name!r}")
    return declaration(name).length


def knob_size_reference(name):
    """What a length knob's size unit is a sixth of: the priors' median longest side for
    the filter's lengths, the MAP object's longest side for the session's."""
    return ("the priors' median longest side" if name in FILTER_KNOBS
            else "the estimated object's longest side")


def value_of(params, name):
    """A declared parameter's value in ``params`` (SessionParams), in its component."""
    return getattr(params.filter if declaration(name).component == "filter" else params, name)


class Signal:
    """A list of callbacks: ``connect(callback)``, ``emit(*args)``."""

    def __init__(self):
        self._callbacks = []

    def connect(self, callback):
        self._callbacks.append(callback)
        return callback

    def disconnect(self, callback):
        self._callbacks.remove(callback)

    def emit(self, *args):
        for callback in list(self._callbacks):
            callback(*args)


class Scene:
    """Ground truth, priors and settings of the app, and the session run on them.

    Parameters
    ----------
    truth_name : str
        A bundled object to start with.
    truth_model : ObjectModel, optional
        An object to start with instead (e.g. read from a mesh file).
    seed : int
        Seeds the truth's pose and the session.
    library : PriorLibrary, optional
        The priors (default: the bundled known set).
    units : str, optional
        The name of the scene's length unit where it has one (a key of
        :data:`tactile_viz.engine.shape.meshes.UNITS`, e.g. ``"m"``), shown on the plots and written
        to exports, and the unit recordings and saved libraries are converted to; None: the
        library's when all its priors name one, else "scene units".
    sensor_noise : tuple of float
        ``(position std in scene units, normal std in degrees)``: what the simulated sensor
        adds and the model assumes (see :class:`~tactile_viz.engine.session.Session`).
    sensor_outliers : float
        The simulated sensor's chance of a wrong contact.
    robot_scene : tactile_viz.engine.scene.Scene, optional
        The robot's world (a table, the reach cone, the tip's radius; default the paper's
        free space, :data:`tactile_viz.engine.scene.FREE`): the truth rests on its table at
        a random stable pose and every session is made in it. Not to be confused with this
        class, the app's model, also called a scene.
    """

    def __init__(self, truth_name="mug_1", seed=0, library=None, strategy="gpis-dhd",
                 preset="recommended", truth_model=None, units=None, sensor_noise=(0.0, 0.0),
                 sensor_outliers=0.0, robot_scene=None):
        self.truth_changed = Signal()
        self.library_changed = Signal()
        self.settings_changed = Signal()
        self.session_reset = Signal()
        self.stepped = Signal()
        self.library = library if library is not None else PriorLibrary.bundled("known")
        self.enabled = {name: True for name in self.library.names}
        self.truth_model = truth_model if truth_model is not None else load_bundled(truth_name)
        self.seed = int(seed)
        if units is not None and units not in UNITS:
            raise ValueError(f"unknown units {units!r}: use one of {', '.join(UNITS)}")
        self.units = units if units is not None else self.library.units
        self.warnings = []  # why the last file read is likely in another unit (one line each)
        self.sensor_noise = tuple(float(v) for v in sensor_noise)
        self.sensor_outliers = float(sensor_outliers)
        if robot_scene is not None and not isinstance(robot_scene, RobotScene):
            raise ValueError(f"robot_scene must be a tactile_viz.engine.scene.Scene, got "
                             f"{type(robot_scene).__name__}")
        self.robot_scene = FREE if robot_scene is None else robot_scene
        self.truth = self._placed(self.truth_model)
        self.recording = None  # (source, recorded steps) while replaying a recording
        if strategy not in STRATEGIES:
            raise ValueError(f"unknown strategy {strategy!r}")
        self.strategy = strategy
        self.presets = dict(SESSION_PRESETS)
        session_preset(preset)  # raises for an unknown name
        self.preset = preset
        self.overrides = {}
        self.session = None
        self.generation = 0

    # ------------------------------------------------------------------ presets
    def preset_names(self):
        """The presets a view offers (the bundled ones, and a loaded session's own)."""
        return list(self.presets)

    def _base_params(self, name):
        try:
            return self.presets[name]
        except KeyError:
            return session_preset(name)  # raises the project's error for an unknown name

    # ------------------------------------------------------------------ settings
    @property
    def params(self):
        """The session parameters: the preset with the user's overrides."""
        return with_changes(self._base_params(self.preset), **self.overrides)

    def parameter(self, name):
        """Current value of a main knob (``sigma_d``, ``sigma_n``, ``n_s``, ``lam``, ``eps``)."""
        params = self.params
        return value_of(params, name)

    def set_parameter(self, name, value):
        """Change a main knob; an invalid value raises ValueError and changes nothing."""
        if name not in KNOBS:
            raise ValueError(f"unknown parameter {name!r}")
        overrides = dict(self.overrides, **{name: value})
        previous, self.overrides = self.overrides, overrides
        try:
            self.params  # noqa: B018 (reading it validates through the dataclasses)
        except ValueError:
            self.overrides = previous
            raise
        log.info("parameter %s = %s", name, value)
        self._settings_changed()

    def set_strategy(self, strategy):
        if strategy not in STRATEGIES:
            raise ValueError(f"unknown strategy {strategy!r}")
        self.strategy = strategy
        log.info("strategy %s", strategy)
        self._settings_changed()

    def set_preset(self, preset):
        self._base_params(preset)  # raises for an unknown name
        self.preset = preset
        self.overrides = {}
        log.info("preset %s", preset)
        self._settings_changed()

    # ------------------------------------------------------------------ lengths
    @property
    def unit_name(self):
        """The scene's length unit as a view names it ("scene units" without a name)."""
        return self.units or SCENE_UNITS

    @property
    def session_params(self):
        """The parameters of the current session (the scene's before one is made)."""
        return self.session.params if self.session is not None else self.params

    def map_model(self, snapshot=None):
        """The MAP object of ``snapshot`` (default the latest), None before a step."""
        snapshot = snapshot or self.latest
        if snapshot is None or self.session is None:
            return None
        library = self.session.library
        if snapshot.map_class in library:
            return library[snapshot.map_class]
        names = self.session.filter.class_names  # a shape the filter holds beyond the library
        return self.session.filter.models[names.index(snapshot.map_class)]

    def _reference_size(self):
        """The active priors' median longest side (the filter's size before a step)."""
        for library in (self.session.library if self.session is not None else None,
                        self.active_library(), self.library):
            if library is not None and len(library):
                return library.reference_size
        return PAPER_SIZE

    @property
    def reference_size(self):
        """The active priors' median longest side, scene units (a view's length scale)."""
        return self._reference_size()

    def truth_size(self, snapshot=None):
        """The longest side (scene units) errors are judged against: the simulated truth's,
        else the MAP object's of ``snapshot`` (default the latest), else the priors' median."""
        if self.truth is not None:
            return self.truth.model.length
        model = self.map_model(snapshot)
        return model.length if model is not None else self._reference_size()

    def error_threshold(self, snapshot=None):
        """The success threshold in scene units: 10% of :meth:`truth_size`."""
        return error_threshold(self.truth_size(snapshot))

    def size_unit(self, snapshot=None):
        """Scene units per size unit of the session's lengths at ``snapshot`` (default the
        latest): ``length_unit``, else a sixth of the MAP object's longest side, else (no
        step yet) of the priors' median longest side, as the session scales them."""
        params = self.session_params
        if params.length_unit:
            return float(params.length_unit)
        model = self.map_model(snapshot)
        return model.size_unit if model is not None else self._reference_size() / PAPER_SIZE

    def eps_length(self, snapshot=None):
        """The DHD stop (eps) in scene units at ``snapshot`` (default the latest)."""
        return self.session_params.eps * self.size_unit(snapshot)

    # ------------------------------------------------------------------ truth
    @staticmethod
    def bundled_objects():
        return bundled_names("all")

    def set_truth_bundled(self, name):
        self._set_truth(load_bundled(name))

    def set_truth_file(self, path):
        """Use a mesh file as the ground truth (MeshError, and no change, if it is bad); a
        file likely in another unit than the priors is taken with a warning."""
        model = ObjectModel.from_file(path)
        self._check_size(path, model, self.library)
        self._set_truth(model)

    def _check_size(self, path, model, library):
        """Keep (and log) the warning of a mesh without a unit whose size is far off the
        priors' (:func:`~tactile_viz.engine.shape.library.size_warning`)."""
        others = [m for m in library if m is not model]
        message = others and size_warning(Path(path).name, model.length,
                                          PriorLibrary(others).reference_size, self.units)
        self.warnings = [message] if message else []
        if message:
            log.warning("%s", message)

    def _set_truth(self, model):
        self.truth_model = model
        self.recording = None
        self.truth = self._placed(model)
        log.info("ground truth %s at the pose of seed %d", model.name, self.seed)
        self.reset()
        self.truth_changed.emit(self.truth)

    def randomize_pose(self, seed):
        """Place the truth at the random pose of ``seed`` (also the session's seed)."""
        self.seed = int(seed)
        self.recording = None
        self.truth = self._placed(self.truth_model)
        log.info("ground truth %s at the pose of seed %d", self.truth_model.name, self.seed)
        self.reset()
        self.truth_changed.emit(self.truth)

    def _placed(self, model):
        """``model`` at the random pose of the seed: resting on the robot scene's table
        when it has one."""
        return make_truth(model, rng=[self.seed, 0], scene=self.robot_scene)

    def set_robot_scene(self, robot_scene):
        """Use another robot scene (:class:`tactile_viz.engine.scene.Scene`): the truth is
        placed anew at the seed's pose in it (on its table) and the session reset; a
        recording stays (its touches are where they were)."""
        if not isinstance(robot_scene, RobotScene):
            raise ValueError(f"robot_scene must be a tactile_viz.engine.scene.Scene, got "
                             f"{type(robot_scene).__name__}")
        self.robot_scene = robot_scene
        log.info("robot scene %s", robot_scene.as_dict())
        if self.recording is None:
            self.truth = self._placed(self.truth_model)
        self.reset()
        self.truth_changed.emit(self.truth)

    # ------------------------------------------------------------------ priors
    def active_library(self):
        """The priors the filter uses (the checked ones)."""
        return self.library.subset([name for name in self.library.names if self.enabled[name]])

    def set_prior_enabled(self, name, enabled):
        self.library[name]  # raises LibraryError for an unknown name
        self.enabled[name] = bool(enabled)
        log.info("prior %s %s", name, "enabled" if enabled else "disabled")
        self.reset()
        self.library_changed.emit(self.library)

    def add_prior_file(self, path, name=None):
        """Load a mesh file as a new prior (MeshError, and no change, if it is bad)."""
        model = ObjectModel.from_file(path, name=name)
        if model.name in self.library:
            raise LibraryError(f"the library already has a prior named {model.name!r}")
        self._check_size(path, model, self.library)
        self._add_prior(model)
        return model

    def _add_prior(self, model):
        self.library.add(model, units=self.units)
        self.enabled[model.name] = True
        log.info("prior %s added", model.name)
        self.reset()
        self.library_changed.emit(self.library)

    def load_library(self, folder):
        """Replace the priors by a saved library (LibraryError, and no change, if corrupt);
        priors saved in another named unit are converted to the scene's."""
        library = PriorLibrary.load(folder, units=self.units)
        self.library = library
        self.enabled = {name: True for name in library.names}
        self.reset()
        self.library_changed.emit(self.library)

    def save_library(self, folder):
        return self.library.save(Path(folder))

    def can_learn(self):
        """True when the latest step has a reconstructed (novel) surface."""
        latest = self.latest
        return latest is not None and latest.gpis_faces is not None and len(latest.gpis_faces) > 0

    def add_learned_shape(self, name=None):
        """Turn the latest reconstruction into a prior named ``name`` and enable it."""
        if not self.can_learn():
            raise SessionError("there is no reconstructed novel shape to add yet")
        name = name or self._free_name(f"learned_{self.truth_model.name}")
        model = self.session.learned_model(name)
        self._add_prior(model)
        return model

    def _free_name(self, base):
        name, index = base, 2
        while name in self.library:
            name, index = f"{base}_{index}", index + 1
        return name

    # ------------------------------------------------------------------ session
    @property
    def latest(self):
        return None if self.session is None else self.session.latest

    @property
    def snapshots(self):
        return [] if self.session is None else list(self.session.snapshots)

    def ensure_session(self):
        """The current session, created on first use with the current settings."""
        if self.session is None:
            library = self.active_library()
            if len(library) == 0:
                raise SessionError("no prior is selected: check at least one in the list")
            if self.recording is not None:
                source, steps = self.recording
                self.session = RecordedSession(steps, library, self.strategy, self.params,
                                               self.seed, source=source,
                                               sensor_noise=self.sensor_noise,
                                               scene=self.robot_scene)
            else:
                self.session = Session.simulated(self.truth, library, self.strategy, self.params,
                                       self.seed, self.sensor_noise,
                                       sensor_outliers=self.sensor_outliers,
                                       scene=self.robot_scene)
        return self.session

    # ------------------------------------------------------------------ recordings
    def open_observations(self, path, topics=None):
        """Step through recorded touches (an observation file, or a ROS 2 bag read with the
        :class:`~tactile_viz.engine.io.bags.BagTopics` ``topics``) instead of the simulator,
        with the current priors and settings; the truth is hidden (a recording has none).
        Positions are converted to the scene's unit as ``replay`` does (a ``# units:``
        line naming another); :attr:`warnings` says when the file is likely in another unit
        than the priors. A bad file raises ObservationFileError and changes nothing. Returns
        the number of recorded steps."""
        steps = read_recording(path, self.units, topics)
        message = recording_file_warning(path, steps, self.active_library(), self.units)
        self.warnings = [message] if message else []
        if message:
            log.warning("%s", message)
        self.recording = (str(path), steps)
        self.truth = None
        log.info("replaying %s (%d steps)", path, len(steps))
        self.reset()
        self.truth_changed.emit(None)
        return len(steps)

    def export(self, folder):
        """Write the current estimate and the touches so far to ``folder`` (see
        :func:`tactile_viz.engine.export_session`); returns the files written."""
        if self.session is None or self.session.step_count == 0:
            raise SessionError("nothing to export: the session has not started")
        written = export_session(self.session, folder, units=self.units)
        log.info("exported step %d to %s", self.session.step_count, folder)
        return written

    def step(self):
        """One step in the calling thread (the app steps in a worker and calls
        :meth:`announce` on the GUI thread instead)."""
        snapshot = self.ensure_session().step()
        self.announce(snapshot)
        return snapshot

    def announce(self, snapshot):
        self.stepped.emit(snapshot)

    def is_current(self, generation):
        """True while ``generation`` (see :attr:`generation`) names the current session."""
        return generation == self.generation

    def reset(self):
        self.session = None
        self.generation += 1
        self.session_reset.emit()

    def _settings_changed(self):
        self.reset()
        self.settings_changed.emit()

    def save_session(self, path):
        if self.session is None or self.session.step_count == 0:
            raise SessionError("nothing to save: the session has not started")
        saved = self.session.save(path)
        log.info("session saved to %s (%d steps)", saved, self.session.step_count)
        return saved

    def load_session(self, path, callback=None):
        """Load a saved session (its truth, priors, settings and steps replace the current
        ones). ``callback(snapshot)`` sees each replayed step (it may raise to cancel)."""
        session = Session.load(path, callback=callback)
        log.info("session loaded from %s (%d steps)", path, session.step_count)
        return self.adopt_session(session)

    def adopt_session(self, session):
        """Make ``session`` (e.g. loaded in another thread) the current one, with its truth,
        priors, strategy, seed and parameters; emits every signal once and ``stepped`` with
        its latest snapshot. Returns True when the prior library was replaced (its names
        differ from the current ones)."""
        replaced = session.library.names != self.library.names
        preset, overrides = self._match_params(session.params)
        if session.truth is not None:
            self.truth_model, self.truth = session.truth.model, session.truth
            self.recording = None
        else:
            steps = getattr(session, "recording", None) or session.recorded_steps()
            self.truth, self.recording = None, (getattr(session, "source", None) or
                                                "a loaded session", steps)
        self.library = session.library
        self.enabled = {name: True for name in self.library.names}
        self.strategy, self.seed = session.strategy, session.seed
        self.robot_scene = getattr(session, "scene", None) or FREE
        self.preset, self.overrides = preset, overrides
        self.session = session
        self.generation += 1
        self.session_reset.emit()
        self.truth_changed.emit(self.truth)
        self.library_changed.emit(self.library)
        self.settings_changed.emit()
        if session.latest is not None:
            self.stepped.emit(session.latest)
        return replaced

    def _match_params(self, params):
        """(preset, overrides) that give ``params``: a bundled preset with some main knobs
        changed if one does, else ``params`` itself as the preset :data:`LOADED_PRESET`."""
        knobs = {name: value_of(params, name) for name in KNOBS}
        self.presets.pop(LOADED_PRESET, None)
        for name, base in self.presets.items():
            if with_changes(base, **knobs) == params:
                return name, {k: v for k, v in knobs.items() if value_of(base, k) != v}
        self.presets[LOADED_PRESET] = params
        return LOADED_PRESET, {}


__all__ = ["KNOBS", "Knob", "SCENE_UNITS", "Scene", "Signal", "knob_length_power",
           "knob_size_reference"]
