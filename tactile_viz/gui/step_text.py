"""What the window says about a step, as text (no Qt): the Loop panel's status line, the
status bar's fields and the plots' note on a novel object.

Lengths are in scene units, to a resolution of 1/600 of the object's size
(:func:`format_length`). A novel object is shown by its novelty evidence and its
reconstruction, not by a pose error or a class posterior against priors it is none of: its
MAP class is named as the prior its reconstruction starts from.
"""

import math

import numpy as np

from ..engine.params import PAPER_SIZE


def format_length(value, size=None):
    """A length in scene units to a resolution of 1/600 of ``size`` (the object's longest
    side; default the paper's 6, two decimals), so that a metric scene is not all zeros."""
    size = PAPER_SIZE if size is None or not size > 0 else float(size)
    decimals = max(0, 2 - math.floor(math.log10(size / PAPER_SIZE)))
    return f"{value:.{decimals}f}"


def error_text(value, size=None):
    """An error in scene units and, with ``size``, its share of the size: "0.25 (4.2%)";
    "-" for None (no truth)."""
    if value is None:
        return "-"
    text = format_length(value, size)
    return text + (f" ({100 * value / size:.1f}%)" if size else "")


def judgement(snapshot):
    """``NOVEL``, or ``known`` with the decision (beyond the paper): ``decided`` once no
    other class or pose fits, else the share the MAP holds so far."""
    if snapshot.novel:
        return "NOVEL"
    confidence = getattr(snapshot, "decision_confidence", 0.0)
    if getattr(snapshot, "decided", False):
        return f"known, decided ({100 * confidence:.1f}%)"
    return f"known, deciding ({100 * confidence:.0f}%)"


def novelty_evidence(snapshot):
    """The novelty test's statistic: the MAP's log evidence against the known/novel
    threshold, e.g. "evidence -312.4, threshold -98.7" (None when not carried)."""
    evidence = getattr(snapshot, "log_evidence", None)
    threshold = getattr(snapshot, "log_threshold", None)
    if evidence is None or threshold is None:
        return None
    return f"evidence {evidence:.1f}, threshold {threshold:.1f}"


def reconstruction_length(snapshot):
    """The longest side of the step's reconstructed surface (scene units; None without
    one)."""
    vertices = getattr(snapshot, "gpis_vertices", None)
    if vertices is None or len(vertices) == 0:
        return None
    return float(np.ptp(np.asarray(vertices, dtype=float), axis=0).max())


def _reconstruction_fields(snapshot, size):
    """A novel step's reconstruction: its error and its size (longest side), the truth's
    beside it when known."""
    length = reconstruction_length(snapshot)
    text = "-" if length is None else format_length(length, size)
    if length is not None and snapshot.recon_error is not None and size:
        text += f" (truth {format_length(size, size)})"
    return [f"recon error {error_text(snapshot.recon_error, size)}", f"size {text}"]


def status_fields(snapshot, size=None):
    """The fields of :func:`status_text`."""
    if snapshot.novel:
        fields = ["NOVEL", f"prior used {prior_used(snapshot)}"]
        evidence = novelty_evidence(snapshot)
        fields += ([evidence] if evidence else []) + _reconstruction_fields(snapshot, size)
    else:
        fields = [judgement(snapshot), f"MAP {snapshot.map_class}",
                  f"pose error {error_text(snapshot.pose_error, size)}"]
        rotation = getattr(snapshot, "rotation_error_deg", None)
        translation = getattr(snapshot, "translation_error", None)
        if rotation is not None and translation is not None:
            fields.append(f"rot {rotation:.1f}\u00b0, shift {format_length(translation, size)}")
        fields.append(f"recon error {error_text(snapshot.recon_error, size)}")
    return fields + [f"particles {snapshot.n_particles}"]


def status_text(snapshot, size=None):
    """One line on a step (the Loop panel's): known (decided or not) with the MAP class,
    errors and particles; or NOVEL with the prior used, the novelty evidence, the
    reconstruction's error and size, and particles (the DHD and the step's time are the
    status bar's).

    Lengths are in scene units; with ``size`` (the longest side the errors are judged
    against, scene units) the errors also give their share of it, e.g. "pose error 0.25
    (4.2%)". The MAP's rotation error (degrees) and translation error follow when the
    snapshot has them (a simulated truth of the MAP's shape). A novel object has no pose
    error: its MAP class is the prior its reconstruction starts from, not the object."""
    return " | ".join(status_fields(snapshot, size))


def summary_text(snapshot, size=None):
    """The status bar's short line on a step: the judgement, the MAP class (a novel
    object's prior used) and the error against the truth when there is one."""
    if snapshot.novel:
        fields = ["NOVEL", f"prior used {prior_used(snapshot)}"]
        error = snapshot.recon_error
        fields += [] if error is None else [f"recon error {error_text(error, size)}"]
    else:
        fields = [judgement(snapshot), f"MAP {snapshot.map_class}"]
        error = snapshot.pose_error
        fields += [] if error is None else [f"pose error {error_text(error, size)}"]
    return " | ".join(fields)


def novelty_note(snapshot):
    """The plots' note in place of the class posterior of a novel step (lines)."""
    lines = ["judged NOVEL: none of these priors"]
    evidence = novelty_evidence(snapshot)
    lines += [f"log {evidence}"] if evidence else []
    return "\n".join(lines + [f"prior used for the reconstruction: {prior_used(snapshot)}"])


def prior_used(snapshot):
    """What a novel step's GPIS started from: the MAP class, or ``ellipsoid fitted`` (a
    superquadric fitted to the contacts, ``gpis_agnostic``)."""
    shape = getattr(snapshot, "gpis_shape", None)
    return snapshot.map_class if shape is None else f"{shape.kind} fitted"


def noise_text(noise, outliers=0.0, unit_name="scene units", size=None):
    """The sensor noise a session assumes (and a simulated sensor adds): ``noise`` is
    ``(position std in scene units, normal std in degrees)``; e.g. "noise 0.0020 m,
    2.0\u00b0, 5% outliers", "noise off"."""
    position, normal = (float(value) for value in noise)
    if not (position or normal or outliers):
        return "noise off"
    text = f"noise {format_length(position, size)} {unit_name}, {normal:.1f}\u00b0"
    return text + (f", {100 * outliers:.0f}% outliers" if outliers else "")


def preset_text(preset, changed=False):
    """The parameter preset, e.g. "preset recommended", "(changed)" when knobs differ."""
    return f"preset {preset}" + (" (changed)" if changed else "")
