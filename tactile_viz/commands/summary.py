"""The few lines a person reads at the end of ``trial`` and ``replay``: what the object
was judged, at which touch, the MAP and its pose, and where the files went."""

import numpy as np
from scipy.spatial.transform import Rotation


def result_summary(result, files=()):
    """Lines summing up a ``trial`` or ``replay`` result dict.

    Parameters
    ----------
    result : dict
        As the commands write it (``steps``, ``units``, ``terminated_at``, ...).
    files : sequence of (str, str)
        ``(what, where)`` of the files written.

    Returns
    -------
    list of str
    """
    steps = result.get("steps") or []
    unit = result.get("units") or "scene units"
    if not steps:
        return ["no step was taken"]
    last = steps[-1]
    touches = f"{last['n_contacts']} contacts, {last['n_noncontacts']} misses"
    if last.get("novel"):
        verdict = f"novel (none of the {len(result.get('library', []))} priors)"
        if last.get("gpis_prior"):
            verdict += f", reconstructed from {_prior_words(last['gpis_prior'], result)}"
    else:
        verdict = f"known: {last['map_class']}"
    decided = result.get("decided_at")
    if decided is not None:
        verdict += f", decided at step {decided}"
    elif not last.get("novel"):
        verdict += ", not decided"
    stop = result.get("terminated_at")
    cap = (result.get("params") or {}).get("max_steps_novel" if last.get("novel")
                                           else "max_steps_known")
    ended = (f"stopped at its step cap ({cap})" if stop is not None and cap and stop >= cap
             else f"stopped by itself at step {stop}" if stop is not None
             else f"ran to step {last['t']} without stopping")
    if result.get("interrupted"):
        ended = f"interrupted at step {last['t']}"
    lines = [f"{result.get('object') or 'the recorded object'}: {verdict}; {ended} "
             f"({touches}, {result.get('seconds', 0.0):.1f} s)"]
    if not last.get("novel") and last.get("map_rotation") is not None:
        turn = Rotation.from_matrix(np.asarray(last["map_rotation"])).as_rotvec()
        angle = float(np.degrees(np.linalg.norm(turn)))
        axis = turn / max(np.linalg.norm(turn), 1e-12)
        where = np.asarray(last["map_translation"], float)
        lines.append(f"  MAP pose: turned {angle:.1f} deg about ({_xyz(axis, 3)}), at "
                     f"({_xyz(where, 4)}) {unit}")
    if last.get("pose_error") is not None and result.get("truth_pose") is not None:
        lines.append(f"  against the truth: pose error {last['pose_error']:.4g} {unit}"
                     + (f", rotation {last['rotation_error_deg']:.2f} deg"
                        if last.get("rotation_error_deg") is not None else ""))
    learned = result.get("learned")
    if isinstance(learned, dict) and learned.get("name"):
        lines.append(f"  learned: {learned['name']}")
    lines += [f"  {what}: {where}" for what, where in files]
    return lines


def _prior_words(prior, result):
    """``the prior mug_1`` or ``an ellipsoid fitted to the contacts``."""
    if prior in result.get("library", []) or prior not in ("ellipsoid", "rounded box", "box"):
        return f"the prior {prior}"
    return f"{'an' if prior == 'ellipsoid' else 'a'} {prior} fitted to the contacts"


def _xyz(values, digits):
    return ", ".join(f"{v:.{digits}g}" for v in values)
