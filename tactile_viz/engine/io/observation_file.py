"""Recorded touches as a CSV file: what a real sensor (or another program) saw, in time order.

The format (documented in the README)::

    # units: mm
    step,kind,x,y,z,nx,ny,nz
    1,contact,0.51,-0.2,1.3,0.0,0.6,0.8
    2,noncontact,2.0,0.4,0.1,,,
    2,free,1.7,0.4,0.1,,,
    2,contact,1.1,0.3,0.2,0.9,0.1,0.4

``kind`` is ``contact`` (a touch: position and outward normal), ``noncontact`` (the sensor
reached the point without touching anything; no normal) or ``free`` (a point the sensor
passed through without touching; it only carves the reconstruction's prior and is not an
observation of the filter; optional). The ``step`` column is optional: rows with the same
step are one update of the filter; without it every row is a step of its own (a ``free`` row
then joins the step of the next observation). Every other column, blank lines and lines
starting with ``#`` are errors or ignored as stated in :func:`read_observations`. An
optional comment ``# units: NAME`` before the header names the positions' unit (m, cm, mm,
in); readers convert them to the scene's unit.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ObservationError
from ..explore.observations import Contact, NonContact
from ..shape.meshes import UNITS
from .files import write_atomic

HEADER = ("kind", "x", "y", "z", "nx", "ny", "nz")
KINDS = ("contact", "noncontact", "free")
SPAN_CONTACTS = 10  # fewer touches may cover a small part of the object: their span says little


class ObservationFileError(ObservationError):
    """An observation file cannot be read: names the file, the line and the fault."""

    def __init__(self, path, line, fault):
        self.path, self.line, self.fault = str(path), line, fault
        where = f"{self.path}, line {line}" if line else self.path
        super().__init__(f"{where}: {fault}")


@dataclass
class RecordedStep:
    """One step of a recording.

    Attributes
    ----------
    observations : list of Contact or NonContact
        What the filter sees, in time order.
    free_space : (k, 3) float
        Points the sensor passed through without touching.
    """

    observations: list = field(default_factory=list)
    free_space: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def _number(text, name, path, line):
    try:
        value = float(text)
    except ValueError:
        raise ObservationFileError(path, line, f"{name} is not a number: {text!r}") from None
    if not math.isfinite(value):
        raise ObservationFileError(path, line, f"{name} is not finite: {text!r}")
    return value


def _row(row, columns, path, line):
    """(step or None, kind, position, normal or None) of one data row."""
    if len(row) != len(columns):
        raise ObservationFileError(path, line, f"expected {len(columns)} fields, got {len(row)}")
    values = dict(zip(columns, (cell.strip() for cell in row)))
    kind = values["kind"]
    if kind not in KINDS:
        raise ObservationFileError(path, line, f"kind must be one of {', '.join(KINDS)}, "
                                               f"got {kind!r}")
    step = None
    if "step" in values:
        try:
            step = int(values["step"])
        except ValueError:
            raise ObservationFileError(path, line, f"step is not an integer: "
                                                   f"{values['step']!r}") from None
    position = [_number(values[name], name, path, line) for name in "xyz"]
    normal_text = [values[name] for name in ("nx", "ny", "nz")]
    if kind != "contact":
        if any(normal_text):
            raise ObservationFileError(path, line, f"a {kind} has no normal; leave nx, ny, nz "
                                                   "empty")
        return step, kind, position, None
    if not all(normal_text):
        raise ObservationFileError(path, line, "a contact needs its normal (nx, ny, nz)")
    normal = [_number(text, name, path, line) for text, name in zip(normal_text,
                                                                    ("nx", "ny", "nz"))]
    return step, kind, position, normal


def _observation(kind, position, normal, path, line):
    try:
        return Contact.recorded(position, normal) if kind == "contact" else NonContact(position)
    except ObservationError as error:
        raise ObservationFileError(path, line, str(error)) from None


def _rows(reader, path):
    """The reader's rows; a line the CSV module cannot split (an overlong field, a NUL)
    is an ObservationFileError naming it."""
    while True:
        try:
            yield next(reader)
        except StopIteration:
            return
        except csv.Error as error:
            raise ObservationFileError(path, reader.line_num, f"not CSV: {error}") from None


def file_units(text, path="<text>"):
    """The unit a ``# units: NAME`` comment before the header names, or None."""
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if not stripped.startswith("#"):
            return None
        key, _, value = stripped.lstrip("#").partition(":")
        if key.strip().lower() == "units":
            name = value.strip().lower()
            if name not in UNITS:
                raise ObservationFileError(path, number, f"unknown units {value.strip()!r}: "
                                                         f"use one of {', '.join(UNITS)}")
            return name
    return None


def parse_observations(text, path="<text>", scale=1.0):
    """The steps of a recording given as CSV text; see :func:`read_observations`."""
    reader = csv.reader(io.StringIO(text))
    columns, steps, keys = None, [], []
    pending_free = []
    for row in _rows(reader, path):
        line = reader.line_num
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        if columns is None:
            columns = tuple(cell.strip() for cell in row)
            body = tuple(c for c in columns if c != "step")
            if body != HEADER or columns.count("step") > 1:
                raise ObservationFileError(path, line, "the header must be "
                                           f"{','.join(HEADER)} (with an optional step "
                                           f"column), got {','.join(columns)}")
            continue
        step, kind, position, normal = _row(row, columns, path, line)
        position = [scale * value for value in position] if scale != 1.0 else position
        key = step if step is not None else len(keys) + 1
        if keys and key != keys[-1] and key < keys[-1]:
            raise ObservationFileError(path, line, f"steps must not decrease (step {key} "
                                                   f"after {keys[-1]})")
        if kind == "free" and step is None:
            pending_free.append(position)
            continue
        if not keys or key != keys[-1] or step is None:
            keys.append(key)
            steps.append(RecordedStep())
        current = steps[-1]
        if kind == "free":
            current.free_space = np.vstack([current.free_space, [position]])
            continue
        current.observations.append(_observation(kind, position, normal, path, line))
        if pending_free:
            current.free_space = np.vstack([current.free_space, pending_free])
            pending_free = []
    if columns is None:
        raise ObservationFileError(path, None, "the file is empty (no header "
                                               f"{','.join(HEADER)})")
    if pending_free:
        raise ObservationFileError(path, None, "free rows at the end belong to no step")
    for number, step in enumerate(steps, start=1):
        if not step.observations:
            raise ObservationFileError(path, None, f"step {keys[number - 1]} has only free "
                                                   "rows: it needs a contact or a non-contact")
    if not steps:
        raise ObservationFileError(path, None, "the file holds no observation")
    return steps


def read_observations(path, units: str | None = None) -> list[RecordedStep]:
    """Read a recording of touches.

    Parameters
    ----------
    path : str or Path
        A CSV file with the header ``kind,x,y,z,nx,ny,nz`` (and optionally ``step``).
    units : str, optional
        The scene's unit (a name of ``UNITS``): positions of a file whose ``# units:``
        comment names another are converted to it. None: positions as written.

    Returns
    -------
    list of RecordedStep
        In time order.

    Raises
    ------
    ObservationFileError
        The file cannot be read or a row is wrong (wrong header, a field that is not a
        number, NaN, a zero normal, a contact without a normal, ...): one error naming the
        file, the line and the fault.
    """
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as error:
        raise ObservationFileError(path, None, f"cannot read the file ({error})") from None
    scale = 1.0
    written = file_units(text, path)
    if units is not None and written is not None:
        scale = UNITS[written] / UNITS[units]
    return parse_observations(text, path, scale)


def recorded_units(path):
    """The unit a recording's ``# units:`` line names, or None (also for an unreadable
    file: :func:`read_observations` reports that)."""
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return None
    return file_units(text, path)


def recording_span(steps):
    """The longest side of the bounding box of a recording's contacts (0 with fewer than
    two), in the units its steps are in: what the touched object's size is at least."""
    points = [o.position for step in steps for o in step.observations if isinstance(o, Contact)]
    if len(points) < 2:
        return 0.0
    points = np.asarray(points, dtype=float)
    return float(np.max(points.max(axis=0) - points.min(axis=0)))


def recording_warning(path, steps, library, units=None):
    """Why the recording ``path`` (read into ``steps``, scene units) is likely not in the
    unit of ``library``, or None: checked unless both the file and the library name their
    unit (see :func:`tactile_viz.engine.shape.library.size_warning`). A recording that spans more
    than ten times the priors' size is suspicious, and so is one of at least
    :data:`SPAN_CONTACTS` contacts that spans less than a tenth of it."""
    from ..shape.library import size_warning

    if len(library) == 0 or (recorded_units(path) is not None and library.units is not None):
        return None
    contacts = sum(isinstance(o, Contact) for step in steps for o in step.observations)
    return size_warning(Path(path).name, recording_span(steps), library.reference_size, units,
                        remedy="add a first line '# units: {unit}' to the file",
                        smaller=contacts >= SPAN_CONTACTS)


def format_observations(steps, units=None):
    """CSV text of recorded steps (a ``step`` column, numbers written exactly).

    Parameters
    ----------
    steps : iterable of RecordedStep or (observations, free_space)
    units : str, optional
        Written as a ``# units:`` comment.

    Returns
    -------
    str
    """
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    if units is not None:
        out.write(f"# units: {units}\n")
    writer.writerow(("step", *HEADER))
    for number, step in enumerate(steps, start=1):
        observations, free_space = (step.observations, step.free_space) if isinstance(
            step, RecordedStep) else step
        for observation in observations:
            position = [repr(float(v)) for v in observation.position]
            if isinstance(observation, Contact):
                normal = [repr(float(v)) for v in observation.normal]
                writer.writerow((number, "contact", *position, *normal))
            else:
                writer.writerow((number, "noncontact", *position, "", "", ""))
        for point in np.reshape(free_space, (-1, 3)):
            writer.writerow((number, "free", *(repr(float(v)) for v in point), "", "", ""))
    return out.getvalue()


def write_observations(path, steps, units: str | None = None):
    """Write recorded steps to ``path`` atomically; see :func:`format_observations`."""
    return write_atomic(path, format_observations(steps, units).encode("utf-8"))


__all__ = ["HEADER", "KINDS", "ObservationFileError", "RecordedStep", "format_observations",
           "parse_observations", "read_observations", "recorded_units", "recording_span",
           "recording_warning", "write_observations"]
