"""Writing a file whole or not at all: the one atomic-write helper of the package.

Saved libraries and sessions, cache entries, generated assets and benchmark records all go
through :func:`write_atomic`, so a killed or failing write never leaves a half file in place
of the last good one, and the file gets the mode ``open()`` would give it.
"""

import os
import tempfile
from pathlib import Path


def current_umask():
    """The process's umask, read without changing it where the system allows.

    Linux reports it in ``/proc/self/status``; elsewhere it is read by setting and restoring
    it, which is not atomic with respect to other threads creating files at that moment.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _sync_folder(folder):
    """Make the rename durable: fsync the folder (not possible on every platform or file
    system; where it is not, the rename is still atomic, only perhaps not yet on disk)."""
    try:
        handle = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(handle)
    except OSError:
        pass
    finally:
        os.close(handle)


def write_atomic(path, data):
    """Replace ``path`` with new contents atomically.

    The contents go to a unique temporary file in the same folder, are flushed and fsynced,
    the file is given mode ``0o666 & ~umask`` (what ``open()`` creates; ``mkstemp``'s own
    0600 would hide saved files from other users) and renamed over ``path``; then the folder
    is synced. On any failure the temporary file is removed and the old ``path``, if any, is
    left as it was.

    Parameters
    ----------
    path : path-like
    data : bytes or callable
        The bytes to write, or a function that writes them to the binary stream it is given
        (e.g. ``lambda stream: np.savez(stream, **arrays)``).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                         suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as stream:
            if callable(data):
                data(stream)
            else:
                stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary, 0o666 & ~current_umask())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    _sync_folder(path.parent)
    return path
