"""How a parameter is declared, once: a dataclass field made by :func:`param`, whose
metadata holds its component, kind, valid range, unit (the power of length of a length in
size units), the range a control offers and a one-line doc. The validation
(:func:`check_fields`), the class docstring's Attributes (:func:`documented`) and the
:class:`Declaration` the GUI, the command line, presets and benchmarks read are derived
from it.
"""

from __future__ import annotations

import math
import numbers
import re
import textwrap
from dataclasses import MISSING, dataclass, field, fields

import numpy as np

from .errors import ParameterError

KINDS = ("float", "int", "bool", "choice", "optional-float")
_INTERVAL = re.compile(r"^([\[(])\s*(-?inf|[-+0-9.e]+)\s*,\s*(-?inf|[-+0-9.e]+)\s*([\])])$")


@dataclass(frozen=True)
class Interval:
    """A range of valid values, written as in mathematics: ``"[0, 0.5)"``, ``"(0, inf)"``."""

    low: float
    high: float
    low_open: bool
    high_open: bool

    @classmethod
    def parse(cls, text):
        match = _INTERVAL.match(text)
        if match is None:
            raise ValueError(f"not an interval: {text!r}")
        left, low, high, right = match.groups()
        return cls(float(low), float(high), left == "(", right == ")")

    def __contains__(self, value):
        low_ok = value > self.low if self.low_open else value >= self.low
        high_ok = value < self.high if self.high_open else value <= self.high
        return bool(low_ok and high_ok and math.isfinite(value))

    def __str__(self):
        def text(bound):
            return "inf" if bound == math.inf else "-inf" if bound == -math.inf else f"{bound:g}"

        return (f"{'(' if self.low_open else '['}{text(self.low)}, {text(self.high)}"
                f"{')' if self.high_open else ']'}")


def param(default=MISSING, doc="", *, component, kind="float", valid=None, length=0,
          unit="", control=None, choices=None, notes="", default_factory=MISSING):
    """A dataclass field declaring one parameter.

    Parameters
    ----------
    default, default_factory
        As for :func:`dataclasses.field`.
    doc : str
        One line: what the parameter does.
    component : str
        Whose parameter it is: ``filter``, ``session``, ``gpis``, ...
    kind : {"float", "int", "bool", "choice", "optional-float"}
        ``int`` accepts an integral float (``30.0``) and stores an int; ``optional-float``
        is None or a number (stored as a float); ``choice`` one of ``choices``.
    valid : str, optional
        The valid range as an interval (``"(0, inf)"``); numbers must also be finite.
    length : int
        The power of length of its unit in size units (0: not a length; 2: a variance).
    unit : str
        The unit's text when it is not a length (``degrees``) or needs more words.
    control : (low, high), optional
        The range a control offers, when narrower than ``valid`` or it is unbounded.
    notes : str
        What the one line leaves out (the docstring shows it below the line).
    """
    if kind not in KINDS:
        raise ValueError(f"unknown kind {kind!r}")
    metadata = {"component": component, "kind": kind, "doc": doc, "notes": notes,
                "length": length, "unit": unit, "choices": tuple(choices or ()),
                "valid": None if valid is None else Interval.parse(valid),
                "control": control}
    return field(default=default, default_factory=default_factory, metadata=metadata)


def check_real(name, value):
    """A real number (not a bool, string or None), else ParameterError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a number, got {value!r}")


def check_integer(name, value):
    """``value`` as an int (an integral float such as ``30.0`` is accepted), else
    ParameterError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be an integer, got {value!r}")
    if isinstance(value, numbers.Integral):
        return int(value)
    if not (np.isfinite(value) and float(value).is_integer()):
        raise ParameterError(f"{name} must be an integer, got {value!r}")
    return int(value)


def checked_value(name, value, kind, valid=None, choices=()):
    """``value`` of the parameter ``name`` as stored (an int for ``int``), else one
    ParameterError naming the parameter, the value and its range (``kind``, ``valid``,
    ``choices`` as for :func:`param`)."""
    if kind == "bool":
        if not isinstance(value, (bool, np.bool_)):
            raise ParameterError(f"{name} must be True or False, got {value!r}")
        return value
    if kind == "choice":
        if value not in choices:
            raise ParameterError(f"{name} must be one of {', '.join(choices)}, "
                                 f"got {value!r}")
        return value
    if kind == "optional-float" and value is None:
        return None
    if kind == "int":
        value = check_integer(name, value)
    else:
        check_real(name, value)
        if kind == "optional-float":
            value = float(value)
    if valid is not None and value not in valid:
        raise ParameterError(f"{name} must lie in {valid}, got {value!r}")
    if valid is None and not math.isfinite(value):
        raise ParameterError(f"{name} must be a finite number, got {value!r}")
    return value


def check_fields(instance):
    """Check every declared field of a frozen dataclass instance, storing the checked
    values (call from ``__post_init__``)."""
    for item in declared_fields(type(instance)):
        meta = item.metadata
        object.__setattr__(instance, item.name, checked_value(
            item.name, getattr(instance, item.name), meta["kind"], meta["valid"],
            meta["choices"]))


def declared_fields(cls):
    """The fields of ``cls`` made by :func:`param`."""
    return [item for item in fields(cls) if "component" in item.metadata]


def length_fields(cls):
    """``{name: power of length}`` of the length fields of a parameter dataclass."""
    return {item.name: item.metadata["length"] for item in declared_fields(cls)
            if item.metadata["length"]}


def unit_text(item):
    """The unit of a declared field as the docs write it."""
    power, unit = item.metadata["length"], item.metadata["unit"]
    if unit or not power:
        return unit
    return {1: "size units", 2: "size units squared", -1: "per size unit"}.get(
        power, f"size units^{power}")


@dataclass(frozen=True)
class Declaration:
    """One parameter as the GUI, the command line, presets and benchmarks see it, read
    from its field (the one place it is declared): its component, default, unit, one-line
    doc, the range a control offers (``low``, ``high``; None: unbounded) and the valid
    range (``valid``)."""

    name: str
    component: str
    default: object
    unit: str
    doc: str
    low: object = None
    high: object = None
    length: int = 0  # the power of length of its unit (0: not a length)
    kind: str = "float"
    valid: Interval | None = None
    choices: tuple = ()

    def check(self, value):
        """``value`` as stored, or a ParameterError naming the parameter and its range."""
        return checked_value(self.name, value, self.kind, self.valid, self.choices)


def declarations_of(cls):
    """``{name: Declaration}`` of the declared fields of ``cls``."""
    out = {}
    for item in declared_fields(cls):
        meta = item.metadata
        default = (item.default_factory() if item.default_factory is not MISSING
                   else item.default)
        low, high = meta["control"] or (None, None)
        if meta["control"] is None and meta["valid"] is not None:
            valid = meta["valid"]  # a control offers closed, finite bounds
            low = valid.low if math.isfinite(valid.low) and not valid.low_open else None
            high = valid.high if math.isfinite(valid.high) and not valid.high_open else None
            if meta["kind"] == "int":
                low, high = (None if b is None else int(b) for b in (low, high))
        out[item.name] = Declaration(item.name, meta["component"], default, unit_text(item),
                                     meta["doc"], low, high, meta["length"], meta["kind"],
                                     meta["valid"], meta["choices"])
    return out


def documented(cls):
    """Class decorator: append the numpydoc Attributes of the declared fields to the
    docstring (type, unit, doc, notes, valid range and default)."""
    lines = ["", "    Attributes", "    ----------"]
    for item in fields(cls):
        meta = item.metadata
        if "component" not in meta:
            lines.append(f"    {item.name} : {getattr(item.type, '__name__', item.type)}")
            continue
        kind = {"optional-float": "float or None", "choice": "{" + ", ".join(
            f'"{c}"' for c in meta["choices"]) + "}"}.get(meta["kind"], meta["kind"])
        unit = unit_text(item)
        lines.append(f"    {item.name} : {kind}" + (f", {unit}" if unit else ""))
        text = meta["doc"] + (" " + meta["notes"] if meta["notes"] else "")
        if meta["valid"] is not None:
            text += f" Valid: {meta['valid']}."
        lines += ["        " + line for line in textwrap.wrap(text, 80, break_on_hyphens=False)]
    cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n" + "\n".join(lines) + "\n    "
    return cls


__all__ = ["Declaration", "Interval", "check_fields", "check_integer", "check_real",
           "declarations_of", "documented", "length_fields", "param"]
