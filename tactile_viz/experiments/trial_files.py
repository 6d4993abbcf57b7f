"""Trial records of the benchmarks on disk: gzip-compressed JSON, one file per trial.

A trial's per-step records take 50-150 kB as indented JSON and about a tenth of that
compressed; with floats kept to six significant digits and compact JSON, half of that
again, so a 10-trial protocol run adds about 3.5 MB to ``results/`` instead of tens
(issue 18). Readers take both ``.json`` (older runs) and ``.json.gz`` files.
"""

import gzip
import json
from pathlib import Path

from ..engine.io.files import write_atomic

SUFFIX = ".json.gz"


def trial_path(folder, key):
    """The file of trial ``key`` in ``folder``: an existing ``.json`` of an older run if
    there is one, else the compressed name new trials get."""
    folder = Path(folder)
    plain = folder / f"{key}.json"
    return plain if plain.exists() else folder / f"{key}{SUFFIX}"


SIGNIFICANT_DIGITS = 6  # of every float a trial file stores (errors, poses, seconds)


def rounded(value, digits=SIGNIFICANT_DIGITS):
    """``value`` (nested dicts and lists) with every float rounded to ``digits``
    significant digits: the last digits of a float are noise to every summary, and
    stored in full they make up half of a compressed trial file."""
    if isinstance(value, float):
        return float(f"{value:.{digits}g}")
    if isinstance(value, dict):
        return {key: rounded(item, digits) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [rounded(item, digits) for item in value]
    return value


def write_trial(folder, key, result):
    """Write one trial record (floats to :data:`SIGNIFICANT_DIGITS` digits, compact JSON)
    compressed and atomically; returns its path."""
    data = gzip.compress(json.dumps(rounded(result), separators=(",", ":")).encode(),
                         mtime=0)
    path = Path(folder) / f"{key}{SUFFIX}"
    written = write_atomic(path, data)
    (Path(folder) / f"{key}.json").unlink(missing_ok=True)  # superseded
    return written


def read_trial(path):
    """One trial record (``.json`` or ``.json.gz``)."""
    path = Path(path)
    data = path.read_bytes()
    if path.name.endswith(".gz"):
        data = gzip.decompress(data)
    return json.loads(data)


def trial_files(folder):
    """Every trial file in ``folder``, sorted by name (without its suffix)."""
    folder = Path(folder)
    files = list(folder.glob("*.json")) + list(folder.glob(f"*{SUFFIX}"))
    return sorted(files, key=lambda p: p.name.removesuffix(".gz").removesuffix(".json"))


def read_trials(folder):
    """Every trial record in ``folder``."""
    return [read_trial(path) for path in trial_files(folder)]


__all__ = ["SIGNIFICANT_DIGITS", "SUFFIX", "read_trial", "read_trials", "rounded", "trial_files",
           "trial_path", "write_trial"]
