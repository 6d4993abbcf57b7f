"""The window's commands as data: one table of actions, and the file commands written once.

In napari's style (``napari/_qt/_qapp_model/qactions/_file.py``) every command is a row of
:data:`ACTIONS`: id, title, shortcut, tooltip, where it is placed (menus and toolbar, by
group) and a callback taking the window. :func:`create_actions` makes the ``QAction``s and
the window builds its menus and toolbar with :func:`placed`.

Every file command has the same shape, so it is written once: a :class:`FileCommand` asks
for a path with a file dialog that starts in the folder last used for that kind of file
(refusing, with a word in the status bar, while steps run), remembers the folder and hands
the path to a window method; a :class:`SceneCall` runs the scene's method on the path,
shows an error in a box (the scene unchanged) or says what was done in the status bar.
"""

import os
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QFileDialog, QMessageBox

from .status_bar import STATUS_SECONDS
from .viewport import MESH_SUFFIXES, is_mesh_path

MESH_FILTER = "Meshes (*.obj *.ply *.stl *.off *.glb *.gltf);;All files (*)"


# ---------------------------------------------------------------------- file commands
def last_folder(settings, kind):
    """The folder last used for ``kind`` of file ("" if none, or it is gone)."""
    folder = settings.value(f"folders/{kind}", "")
    return folder if isinstance(folder, str) and os.path.isdir(folder) else ""


def remember_folder(settings, kind, path):
    path = Path(path)
    settings.setValue(f"folders/{kind}", str(path if path.is_dir() else path.parent))


@dataclass(frozen=True)
class SceneCall:
    """A scene method taking a path: an error goes in a box (the scene unchanged), success
    is said in the status bar. Called as ``call(window, path)``, or as a method of the
    window it is a class attribute of; True if it worked.

    ``busy``, if given, refuses the call while steps run ("Pause first: <busy> changes the
    scene"); ``report(scene, path)`` is the status-bar line.
    """

    method: str
    report: Callable
    busy: str | None = None

    def __get__(self, window, owner=None):
        """As a class attribute of the window, a method: ``window.load_truth_file(path)``."""
        return self if window is None else partial(self, window)

    def __call__(self, window, path):
        if self.busy and not window.idle(self.busy):
            return False
        if not window.guarded(getattr(window.scene, self.method), path):
            return False
        window.statusBar().showMessage(self.report(window.scene, path), STATUS_SECONDS)
        return True


LOAD_TRUTH = SceneCall("set_truth_file", lambda scene, path: f"ground truth: {path}",
                       busy="a new ground truth")
ADD_PRIOR = SceneCall("add_prior_file",
                      lambda scene, path: f"added the prior {scene.library.names[-1]!r}",
                      busy="a new prior")
LOAD_LIBRARY = SceneCall("load_library",
                         lambda scene, folder: f"loaded {len(scene.library)} priors from {folder}")
SAVE_LIBRARY = SceneCall("save_library",
                         lambda scene, folder: f"saved {len(scene.library)} priors to {folder}")
SAVE_SESSION = SceneCall("save_session", lambda scene, path: (
    f"saved the session ({scene.latest.step} steps) to {path}"))
OPEN_OBSERVATIONS = SceneCall("open_observations", lambda scene, path: (
    f"replaying {path}: {len(scene.recording[1])} recorded steps; Step or Run to go "
    "through them"), busy="opening observations")
EXPORT = SceneCall("export", lambda scene, folder: f"exported step {scene.latest.step} to {folder}")


@dataclass(frozen=True)
class FileCommand:
    """Ask for a path, then hand it to the window method ``then``. Called as
    ``command(window)``; returns what ``then`` returned, False if refused or cancelled.

    Parameters
    ----------
    dialog : {"open", "save", "folder"}
        QFileDialog's getOpenFileName, getSaveFileName or getExistingDirectory.
    caption : str
    folder : str
        The kind of file: the dialog starts in the folder last used for it (settings key
        ``folders/<folder>``), which is updated with the answer.
    then : str
        The window method called with the path.
    busy : str, optional
        Refused while steps run, saying "Pause first: <busy> changes the scene".
    filter, name : str
        The dialog's file filter; the file name a save dialog proposes.
    """

    dialog: str
    caption: str
    folder: str
    then: str
    busy: str | None = None
    filter: str = ""
    name: str = ""

    def __call__(self, window):
        if self.busy and not window.idle(self.busy):
            return False
        start = last_folder(window.settings, self.folder)
        if self.dialog == "folder":
            path = QFileDialog.getExistingDirectory(window, self.caption, start)
        elif self.dialog == "open":
            path, _ = QFileDialog.getOpenFileName(window, self.caption, start, self.filter)
        else:
            path, _ = QFileDialog.getSaveFileName(window, self.caption,
                                                  os.path.join(start, self.name), self.filter)
        if not path:
            return False
        remember_folder(window.settings, self.folder, path)
        return getattr(window, self.then)(path)


OPEN_TRUTH_FILE = FileCommand("open", "Open ground-truth mesh", "meshes", "load_truth_file",
                              busy="a new ground truth", filter=MESH_FILTER)
OPEN_PRIOR_FILE = FileCommand("open", "Load a mesh as a prior", "meshes", "add_prior_file",
                              busy="a new prior", filter=MESH_FILTER)
OPEN_LIBRARY = FileCommand("folder", "Load a prior library folder", "library", "load_library",
                           busy="a new library")
SAVE_LIBRARY_TO = FileCommand("folder", "Save the prior library to a folder", "library",
                              "save_library", busy="saving")
SAVE_SESSION_AS = FileCommand("save", "Save session", "sessions", "save_session", busy="saving",
                              filter="Sessions (*.npz)", name="session.npz")
OPEN_SESSION = FileCommand("open", "Load session", "sessions", "load_session",
                           busy="loading a session", filter="Sessions (*.npz)")
OPEN_OBSERVATIONS_FILE = FileCommand("open", "Open observations", "observations",
                                     "open_observations", busy="opening observations",
                                     filter="Observations (*.csv *.mcap *.db3);;All files (*)")
EXPORT_TO = FileCommand("folder", "Export estimate to folder", "exports", "export",
                        busy="exporting")
SAVE_SCREENSHOT_AS = FileCommand("save", "Save screenshot", "screenshots", "save_screenshot",
                                 filter="PNG images (*.png)", name="tactile_viz.png")
RECORD_TO = FileCommand("save", "Record steps", "screenshots", "start_recording",
                        filter="Animated GIF (*.gif);;MP4 video (*.mp4)", name="tactile_viz.gif")


def save_screenshot(window, path):
    """A PNG of the whole window (viewport, docks, plots); True if it was written."""
    if window.grab().save(str(path)):
        window.statusBar().showMessage(f"saved a screenshot to {path}", STATUS_SECONDS)
        return True
    window.show_error(OSError(f"cannot write the screenshot {path}"))
    return False


def open_truth_file(window):
    OPEN_TRUTH_FILE(window)
    window.scene_panel.sync(window.scene)  # the object box back from "Open file..."


def toggle_recording(window, checked):
    if not checked:
        window.stop_recording()
    elif not RECORD_TO(window):  # cancelled, or the file cannot be written
        window.show_recording(False)


# ---------------------------------------------------------------------- drops
def drag_entered(window, paths, accepted):
    """Say in the status bar what a drop would do (or why it is refused)."""
    status = window.statusBar()
    if not paths:
        status.showMessage("only mesh files (" + " ".join(MESH_SUFFIXES) + ") and recorded "
                           "touches (.csv, .mcap, .db3) can be dropped here", STATUS_SECONDS)
    elif not accepted:
        window.idle("a dropped file")  # says: Pause first
    elif not is_mesh_path(paths[0]):
        status.showMessage(f"drop to replay the touches recorded in {Path(paths[0]).name}",
                           STATUS_SECONDS)
    else:
        status.showMessage(f"drop to use {Path(paths[0]).name} as the object; hold Shift to "
                           "add it as a prior", STATUS_SECONDS)


def drop_files(window, paths, as_prior=False):
    """Files dropped on the viewport, through the scene like the File menu's: recorded
    touches (.csv) are replayed; a mesh becomes the ground truth, or with ``as_prior``
    (Shift held) every dropped mesh is added as a prior."""
    if not paths or not window.idle("a dropped file"):
        return
    paths = [str(path) for path in paths]
    if as_prior and is_mesh_path(paths[0]):
        for path in paths:
            if not (is_mesh_path(path) and window.add_prior_file(path)):
                break
        return
    if is_mesh_path(paths[0]):
        done = window.load_truth_file(paths[0])
    else:
        done = window.open_observations(paths[0])
    if done and len(paths) > 1:
        window.statusBar().showMessage(f"{len(paths)} files dropped: used the first, "
                                       f"{Path(paths[0]).name}", STATUS_SECONDS)


# ---------------------------------------------------------------------- help
def show_keys(window):
    rows = "".join(f"<tr><td><b>{window.actions[entry.id].shortcut().toString()}</b></td>"
                   f"<td>{entry.title}</td></tr>"
                   for entry in ACTIONS if not window.actions[entry.id].shortcut().isEmpty())
    QMessageBox.information(window, "Keys", "<table cellspacing=4>" + rows + "</table>"
                            "<p>In the viewport: drag to rotate, shift-drag to pan, "
                            "wheel to zoom; drop a mesh file to use it as the ground "
                            "truth (hold Shift to add it as a prior instead), or an "
                            "observation file (.csv) or ROS 2 bag (.mcap, .db3) to replay it.</p>")


def show_about(window):
    QMessageBox.about(window, "About tactile_viz",
                      "tactile_viz: active tactile object recognition, pose estimation "
                      "and shape transfer (Zheng et al.).")


# ---------------------------------------------------------------------- the table
@dataclass(frozen=True)
class Action:
    """One command of the window.

    ``callback(window)``, or ``callback(window, checked)`` if ``checkable``. ``places``
    pairs a menu id of :data:`MENUS` (or "toolbar") with a group: a group's entries are
    together in table order, groups apart. ``changes_scene``: disabled while steps run or a
    session loads. The shortcuts are listed in Help > Keys, in table order.
    """

    id: str
    title: str
    callback: Callable
    shortcut: object = None  # a key sequence string or a QKeySequence.StandardKey
    tooltip: str | None = None
    places: tuple = ()
    checkable: bool = False
    changes_scene: bool = False


MENUS = (("file", "&File"), ("run", "&Run"), ("view", "&View"), ("help", "&Help"))
_LOOP = (("run", 0), ("toolbar", 0))
_VIEW = (("view", 0), ("toolbar", 1))


def _view(method):
    return lambda window: window.look(method)


ACTIONS = (
    Action("step", "Step", lambda window: window.start(1), "F6", "One step", _LOOP,
           changes_scene=True),
    Action("run", "Run", lambda window, checked: window.run_toggled(checked), "F5",
           "Run continuously; press again to pause (after the step in progress)", _LOOP,
           checkable=True),
    Action("finish", "Run to termination", lambda window: window.start(None), "Shift+F5",
           "Run until the DHD stop or the step cap", _LOOP, changes_scene=True),
    Action("reset", "Reset", lambda window: window.reset_session(), "Ctrl+R",
           "Start a new session on the same scene", _LOOP, changes_scene=True),
    Action("camera", "Reset camera", lambda window: window.frame_truth(), "Home",
           "Frame the ground truth", _VIEW),
    Action("iso", "Isometric view", _view("view_isometric"), "Ctrl+0",
           "Look from the isometric direction", _VIEW),
    Action("xy", "Top view", _view("view_xy"), "Ctrl+1", "Look down the z axis", _VIEW),
    Action("xz", "Front view", _view("view_xz"), "Ctrl+2", "Look along the y axis", _VIEW),
    Action("yz", "Side view", _view("view_yz"), "Ctrl+3", "Look along the x axis", _VIEW),
    Action("screenshot", "Save screenshot...", SAVE_SCREENSHOT_AS, "F12",
           "Save a PNG of the whole window", (("file", 3), ("toolbar", 2))),
    Action("record", "Record steps...", toggle_recording, "Ctrl+Shift+R",
           "Record the window at every drawn step to a GIF or MP4; press again to stop",
           (("file", 3), ("toolbar", 2)), checkable=True),
    Action("open_truth", "Open ground-truth mesh...", open_truth_file,
           QKeySequence.StandardKey.Open, places=(("file", 0),), changes_scene=True),
    Action("load_library", "Load prior library...", OPEN_LIBRARY, places=(("file", 0),),
           changes_scene=True),
    Action("save_library", "Save prior library...", SAVE_LIBRARY_TO, places=(("file", 0),),
           changes_scene=True),
    Action("load_session", "Load session...", OPEN_SESSION, "Ctrl+L", places=(("file", 1),),
           changes_scene=True),
    Action("open_observations", "Open observations...", OPEN_OBSERVATIONS_FILE,
           "Ctrl+Shift+O", "Step through recorded touches (CSV: kind,x,y,z,nx,ny,nz) in this "
           "viewport", (("file", 2),), changes_scene=True),
    Action("export", "Export estimate...", EXPORT_TO, "Ctrl+E",
           "Write observations.csv, map_shape.ply, reconstruction.ply and estimate.json of "
           "the current step to a folder", (("file", 2),), changes_scene=True),
    Action("save_session", "Save session...", SAVE_SESSION_AS, QKeySequence.StandardKey.Save,
           places=(("file", 1),), changes_scene=True),
    Action("quit", "Quit", lambda window: window.close(), QKeySequence.StandardKey.Quit,
           places=(("file", 4),)),
    Action("keys", "Keys", show_keys, "F1", "The keyboard shortcuts", (("help", 0),)),
    Action("about", "About tactile_viz", show_about, places=(("help", 0),)),
)


def create_actions(window):
    """A ``QAction`` per row of :data:`ACTIONS`, added to ``window`` (so that the shortcuts
    work wherever the focus is in it); ``{id: QAction}``."""
    actions = {}
    for entry in ACTIONS:
        action = QAction(entry.title, window)
        if entry.shortcut is not None:
            action.setShortcut(QKeySequence(entry.shortcut))
        if entry.tooltip:
            action.setToolTip(f"{entry.tooltip} ({action.shortcut().toString()})"
                              if entry.shortcut else entry.tooltip)
        if entry.checkable:
            action.setCheckable(True)
            action.toggled.connect(lambda checked, call=entry.callback: call(window, checked))
        else:
            action.triggered.connect(lambda checked=False, call=entry.callback: call(window))
        actions[entry.id] = action
        window.addAction(action)
    return actions


def placed(where):
    """The ids of the actions placed in menu ``where`` (or "toolbar"), by group then in
    table order, with None between groups (a separator)."""
    rows = sorted((group, index, entry.id) for index, entry in enumerate(ACTIONS)
                  for place, group in entry.places if place == where)
    ids = []
    for position, (group, _, name) in enumerate(rows):
        if position and group != rows[position - 1][0]:
            ids.append(None)
        ids.append(name)
    return ids


def scene_actions():
    """The ids of the actions that change the scene (disabled while steps run)."""
    return [entry.id for entry in ACTIONS if entry.changes_scene]
