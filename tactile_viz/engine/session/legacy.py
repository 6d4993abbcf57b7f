"""The deprecated signature of :class:`~.loop.Session`, ``Session(truth, library, ...,
sensor_outliers=...)`` (before 2026-12): mapped to the new one with a warning."""

import warnings

from ..explore.simulator import GroundTruth

_LEGACY_ORDER = ("truth", "library", "strategy", "params", "seed", "sensor_noise", "sensor",
                 "sensor_outliers", "scene")


def legacy_arguments(args, kwargs):
    """``(truth, outliers, args, kwargs)`` of a :class:`Session` call: a call with the old
    signature (the truth, or None, first; or ``truth=``) warns and is mapped to the new one."""
    if not ("truth" in kwargs or (args and (args[0] is None
                                            or isinstance(args[0], GroundTruth)))):
        return None, 0.0, args, kwargs
    warnings.warn("Session(truth, library, ...) is deprecated: use Session.simulated(truth, "
                  "library, ...) for a simulated trial and Session(library, ...) otherwise",
                  DeprecationWarning, stacklevel=3)
    bound = dict(zip(_LEGACY_ORDER, args))
    for name, value in kwargs.items():
        if name in bound:
            raise TypeError(f"Session() got multiple values for argument {name!r}")
        bound[name] = value
    truth, outliers = bound.pop("truth", None), bound.pop("sensor_outliers", 0.0)
    if truth is not None:
        bound.pop("sensor", None)  # the old signature ignored a sensor beside a truth
    return truth, outliers, (), bound
