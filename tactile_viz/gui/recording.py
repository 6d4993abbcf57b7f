"""Recording the drawn steps as an animated GIF or an MP4 (imageio).

A :class:`Recorder` takes RGB frames of any size (each is scaled to the first frame's size)
and writes them with imageio: GIF through Pillow, MP4 through imageio-ffmpeg when it is
installed. The recorder knows nothing of Qt; :func:`widget_frame` turns a widget's grab into
a frame, and :func:`start_recording` / :func:`stop_recording` (methods of the main window)
record the window at every drawn step, its record action checked meanwhile.
"""

from pathlib import Path

import numpy as np

FORMATS = {".gif": "GIF", ".mp4": "MP4"}


class Recorder:
    """Frames to a GIF or MP4 file.

    Parameters
    ----------
    path : str or Path
        Ends in ``.gif`` or ``.mp4``.
    fps : float
        Frames per second of the animation.

    Raises
    ------
    OSError
        For another suffix, an MP4 without imageio-ffmpeg, or a file that cannot be opened.
    """

    def __init__(self, path, fps=5.0):
        import imageio.v2 as imageio

        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in FORMATS:
            raise OSError(f"cannot record to {self.path.name}: use a .gif or .mp4 file")
        if suffix == ".mp4":
            try:
                import imageio_ffmpeg  # noqa: F401
            except ImportError as error:
                raise OSError("MP4 recording needs imageio-ffmpeg (pip install "
                              "imageio-ffmpeg); a .gif needs nothing more") from error
            self._writer = imageio.get_writer(self.path, fps=fps, macro_block_size=1)
        else:
            self._writer = imageio.get_writer(self.path, mode="I", duration=1.0 / fps, loop=0)
        self.size = None
        self.frames = 0

    def add(self, frame):
        """Append an (h, w, 3) uint8 frame; returns the number of frames so far."""
        frame = np.asarray(frame, dtype=np.uint8)
        if self.size is None:
            self.size = frame.shape[:2]
        elif frame.shape[:2] != self.size:
            frame = _resized(frame, self.size)
        self._writer.append_data(frame)
        self.frames += 1
        return self.frames

    def close(self):
        self._writer.close()
        return self.path


def _resized(frame, size):
    """Nearest-neighbour resize of an (h, w, 3) frame to ``size`` (rows, columns)."""
    rows = np.linspace(0, frame.shape[0] - 1, size[0]).round().astype(int)
    columns = np.linspace(0, frame.shape[1] - 1, size[1]).round().astype(int)
    return frame[rows][:, columns]


def widget_frame(widget):
    """An (h, w, 3) uint8 RGB array of ``widget`` as it is drawn (its grab)."""
    from PySide6.QtGui import QImage

    image = widget.grab().toImage().convertToFormat(QImage.Format_RGB888)
    width, height = image.width(), image.height()
    buffer = np.frombuffer(image.constBits(), dtype=np.uint8)
    rows = buffer.reshape(height, image.bytesPerLine())
    return rows[:, :3 * width].reshape(height, width, 3).copy()


def start_recording(window, path):
    """Record the whole window at every drawn step to ``path`` (.gif or .mp4); False, with
    an error box, if the file cannot be written."""
    from .status_bar import STATUS_SECONDS

    window.stop_recording()
    try:
        window.recorder = Recorder(path)
    except OSError as error:
        window.show_error(error)
        return False
    window.show_recording(True)
    window.statusBar().showMessage(f"recording the drawn steps to {path}", STATUS_SECONDS)
    return True


def stop_recording(window):
    """Finish the window's recording, if any; returns its path."""
    from .status_bar import STATUS_SECONDS

    recorder, window.recorder = window.recorder, None
    window.show_recording(False)
    if recorder is None:
        return None
    path = recorder.close()
    window.statusBar().showMessage(f"saved {recorder.frames} frames to {path}", STATUS_SECONDS)
    return path


def show_recording(window, recording):
    """Check the window's record action (or not), without toggling a recording."""
    from .panels.base import blocked

    with blocked(window.actions["record"]):
        window.actions["record"].setChecked(recording)
