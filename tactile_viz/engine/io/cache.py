"""An on-disk cache of derived arrays (SDF grids, feature points, pair tables).

Entries are keyed by the content hash of the mesh and the parameters that made them, so a
changed mesh or parameter never reads a stale entry. Files are written atomically; a
corrupt or unreadable entry is treated as missing and rebuilt.
"""

import hashlib
import json
import logging
import os
import zipfile
from pathlib import Path

import numpy as np

from .files import write_atomic

ENV_VAR = "TACTILE_VIZ_CACHE"
log = logging.getLogger(__name__)


def default_cache_dir():
    """``$TACTILE_VIZ_CACHE``, else ``$XDG_CACHE_HOME/tactile_viz``, else
    ``~/.cache/tactile_viz``."""
    if os.environ.get(ENV_VAR):
        return Path(os.environ[ENV_VAR])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "tactile_viz"


class ArrayCache:
    """Arrays stored as ``.npz`` files under one folder.

    Parameters
    ----------
    folder : path-like or None
        ``None`` uses :func:`default_cache_dir`. ``False`` disables the disk (memory only).
    """

    def __init__(self, folder=None):
        self.folder = None if folder is False else Path(folder or default_cache_dir())

    def key(self, kind, content_hash, params):
        """File name of an entry: the kind plus a hash of content and parameters."""
        text = json.dumps({"content": content_hash, "params": params}, sort_keys=True)
        return f"{kind}-{hashlib.sha256(text.encode()).hexdigest()[:32]}.npz"

    def has(self, kind, content_hash, params) -> bool:
        """Whether the entry is stored on disk (False when the disk is disabled)."""
        return self.folder is not None and (
            self.folder / self.key(kind, content_hash, params)).is_file()

    def get_or_build(self, kind, content_hash, params, build):
        """Load an entry, or build it with ``build()`` (a dict of arrays) and store it."""
        if self.folder is None:
            return build()
        path = self.folder / self.key(kind, content_hash, params)
        try:
            with np.load(path, allow_pickle=False) as stored:
                return {name: stored[name] for name in stored.files}
        except FileNotFoundError:
            log.debug("cache: building %s", path.name)
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as error:
            log.warning("cache: rebuilding the unreadable entry %s (%s)", path, error)
        arrays = build()
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            write_atomic(path, lambda stream: np.savez(stream, **arrays))
        except OSError as error:  # a read-only cache folder only costs time
            log.debug("cache: cannot store %s (%s)", path, error)
        return arrays

