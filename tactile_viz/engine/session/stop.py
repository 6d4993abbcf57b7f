"""When a session stops: Algorithm 2's l.1, ``d_H(S*, X_c) <= eps``, and what holds it.

The paper stops as soon as the contacts cover the estimate. Beyond the paper the stop also
waits for check lines and the frontier (a novel object), for rival hypotheses to be told
apart, for the one hypothesis left to be posed, for the decision's confirm checks and
while a misfitting MAP's count toward novelty runs (a known object); a decision can stop
a session by itself (``stop_at_decision``); the step cap always does. Every rule is here,
as plain functions of the step's figures and the parameters in scene units, so that
changing the stop means editing this module only; :meth:`~.planner.Planner.stop_test`
gathers their inputs.
"""

from typing import NamedTuple

import numpy as np


class Stop(NamedTuple):
    """The stop test of a step (l.1) with what holds it (beyond the paper)."""

    terminated: bool
    decided: bool
    frontier: bool  # a frontier target is queued
    checking: bool  # a check line is due
    confirm: bool  # a confirm check of the decision is due
    rivals: bool  # rival hypotheses are to be told apart
    posing: bool  # the one hypothesis left is to be posed better
    decision_checks: int  # confirm checks passed (0: the MAP no longer qualifies)


# A known judgement within this many steps of a novel one is a flicker while its MAP
# misfits: the same fork in `many` at 2 mm, novel until touch 81, stopped judged known at
# touch 84 as a knife whose fit's p-value was 1.5e-4.
FLICKER_STEPS = 5


class Progress(NamedTuple):
    """What a session has done so far that the stop reads (the exploration state's).

    Attributes
    ----------
    step : int
        Steps taken before this one.
    frontier_queued : bool
        A frontier target is waiting.
    checks_passed : int
        Check lines in a row that touched nothing unpredicted.
    decision_checks : int
        Confirm checks of the decision passed so far.
    telling_steps : int
        Steps spent telling hypotheses apart or posing the MAP.
    misfit_steps : int
        Steps in a row, this one included, that a known MAP misfitted
        (:meth:`~.planner.Planner.misfits`; 0 without ``misfit_novelty``).
    recently_novel : bool
        One of the last ``FLICKER_STEPS`` steps before this one judged the object novel.
    """

    step: int
    frontier_queued: bool
    checks_passed: int
    decision_checks: int
    telling_steps: int
    misfit_steps: int = 0
    recently_novel: bool = False


def decision_ready(p, decision, dhd, checks_done):
    """``(decided, confirm, decision_checks)``: the step's decision needs contacts all
    around the MAP (its DHD ``dhd`` within ``decision_cover``) and, with
    ``decision_targets``, ``decision_checks`` sweeps just outside it that touched nothing it
    does not predict (``confirm``: plan the next); a MAP that no longer qualifies starts
    the count again (the count returned)."""
    ready = decision.decided and dhd <= p.decision_cover
    count = checks_done if ready else 0
    if not p.decision_targets:
        return ready, False, count
    confirm = ready and count < p.decision_checks
    return ready and not confirm, confirm, count


def stop_rule(p, covered_dhd, map_dhd, novel, exploring, decision, progress, noise=0.0):
    """The :class:`Stop` of a step.

    Parameters
    ----------
    p : SessionParams
        In scene units.
    covered_dhd : float
        ``d_H(S*, X_c)``, with the prior's cover (``Coverage.value``).
    map_dhd : float
        The DHD of the surface the decision is judged on (``Coverage.dhd``).
    novel : bool
        The object is judged novel.
    exploring : bool
        Novel and reconstructing (not the RRT strategy): checks and the frontier apply.
    decision : Decision
    progress : Progress
    noise : float, scene units
        The sensor's position noise (std): a known object is covered within
        ``hypot(eps, cover_noise_stds * noise)``.

    Returns
    -------
    Stop
    """
    # A known judgement soon after a novel one whose MAP misfits the noise stops nothing
    # (misfit_novelty) and keeps the novel cap: the paper's test flickers on a novel
    # object under noise (a 20 cm fork judged novel for most of 305 touches stopped
    # judged known at the 306th, past the known cap).
    flicker = (p.misfit_novelty > 0 and not novel and progress.recently_novel
               and not decision.fits)
    cap = p.max_steps_novel if novel or flicker else p.max_steps_known
    reach = p.eps if novel else float(np.hypot(p.eps, p.cover_noise_stds * noise))
    covered = covered_dhd <= reach                                      # l.1
    frontier = exploring and progress.frontier_queued
    checking = (covered and exploring and not frontier
                and progress.checks_passed < p.check_lines)
    decided, confirm, decision_checks = decision_ready(p, decision, map_dhd,
                                                       progress.decision_checks)
    patient = progress.telling_steps < p.decision_patience
    # Rivals are aimed at (and the DHD stop waits) only while the MAP fits within the
    # noise (else the object is none of them) and for decision_patience steps at most.
    rivals = (p.decision_targets and not novel and not decided and not confirm
              and decision.fits and len(decision.rivals) > 0 and patient)
    # So is the MAP, once it is the one hypothesis left but its pose is not yet known well
    # enough (a 2 cm block under 2 mm noise) or the filter's posterior not yet held by the
    # classes weighed (a fork's spread over four thin classes, 0.988 when its surface was
    # covered), within the same patience.
    settling = (decision.fits and bool(decision.hypotheses)
                and decision.hypotheses[0].probability >= p.decision_confidence)
    # A session that stops at the decision also waits while a known MAP does not yet fit
    # within the noise (17 touches of a pencil at 2 mm, 2.5 times their expected
    # residuals, covered it): more touches fit it, or judge the object novel.
    doubting = p.stop_at_decision and bool(decision.hypotheses) and not decision.fits
    posing = (p.decision_targets and not novel and not rivals and not decided
              and (decision.loosest is not None or settling or doubting) and patient)
    # Nor does a known object stop while its MAP misfits and the count that judges it
    # novel runs (misfit_novelty): a 20 cm fork covered as a 25 cm knife stopped at the
    # first of the five steps, its rivals and pose no longer held open by a fit.
    misfitting = not novel and progress.misfit_steps > 0
    # The DHD stop waits for the decision's checks too: they are a step or two, and a thin
    # object is covered before they are swept (an 18 cm pencil in 15 touches).
    terminated = bool((covered and not checking and not frontier and not rivals
                       and not posing and not confirm and not misfitting and not flicker)
                      or (p.stop_at_decision and decided)
                      or progress.step + 1 >= cap)
    return Stop(terminated, decided, frontier, checking, confirm, rivals, posing,
                decision_checks)
