"""The stop rule (engine/session/stop.py) on its own: no session, no filter."""

import numpy as np
import pytest

from tactile_viz.engine.belief.decision import UNDECIDED, Decision, Hypothesis
from tactile_viz.engine.presets import session_preset
from tactile_viz.engine.session.stop import Progress, decision_ready, stop_rule

FRESH = Progress(step=10, frontier_queued=False, checks_passed=0, decision_checks=0,
                 telling_steps=0)


def _hypothesis(probability):
    return Hypothesis(0, np.eye(3), np.zeros(3), 0.0, probability)


def _decided(rivals=0):
    others = tuple(_hypothesis(0.2) for _ in range(rivals))
    return Decision(True, 0.999, (_hypothesis(0.999),) + others, fits=True)


def test_the_paper_stops_as_soon_as_the_estimate_is_covered():
    p = session_preset("paper")
    for novel in (True, False):
        assert stop_rule(p, p.eps, p.eps, novel, novel, UNDECIDED, FRESH).terminated
        assert not stop_rule(p, 1.01 * p.eps, 0.0, novel, novel, UNDECIDED, FRESH).terminated


@pytest.mark.parametrize("novel, cap", [(True, "max_steps_novel"), (False, "max_steps_known")])
def test_the_step_cap_stops_whatever_holds(novel, cap):
    p = session_preset("recommended")
    last = FRESH._replace(step=getattr(p, cap) - 1)
    assert stop_rule(p, 10 * p.eps, 10 * p.eps, novel, novel, UNDECIDED, last).terminated
    assert not stop_rule(p, 10 * p.eps, 10 * p.eps, novel, novel, UNDECIDED,
                         last._replace(step=last.step - 1)).terminated


def test_a_covered_novel_estimate_waits_for_its_checks_and_frontier():
    p = session_preset("recommended")
    stop = stop_rule(p, p.eps, p.eps, True, True, UNDECIDED, FRESH)
    assert stop.checking and not stop.terminated
    passed = FRESH._replace(checks_passed=p.check_lines)
    assert stop_rule(p, p.eps, p.eps, True, True, UNDECIDED, passed).terminated
    queued = passed._replace(frontier_queued=True)
    stop = stop_rule(p, p.eps, p.eps, True, True, UNDECIDED, queued)
    assert stop.frontier and not stop.checking and not stop.terminated
    # RRT explores without checks: covered is enough.
    assert stop_rule(p, p.eps, p.eps, True, False, UNDECIDED, FRESH).terminated


def test_a_known_flicker_after_novel_steps_stops_only_on_a_fitting_map():
    p = session_preset("recommended")
    after_novel = FRESH._replace(recently_novel=True)
    misfit = Decision(False, 0.9, (_hypothesis(0.9),), fits=False)
    # The paper's test judging a novel object known for one step: no stop, the novel cap.
    assert not stop_rule(p, p.eps, p.eps, False, False, misfit, after_novel).terminated
    at_known_cap = after_novel._replace(step=p.max_steps_known - 1)
    assert not stop_rule(p, p.eps, p.eps, False, False, misfit, at_known_cap).terminated
    # A MAP that fits stops as before, so does one known for two steps, and the paper.
    fitting = Decision(False, 0.5, (_hypothesis(0.5),), fits=True)
    assert stop_rule(p, p.eps, p.eps, False, False, fitting, after_novel).terminated
    assert stop_rule(p, p.eps, p.eps, False, False, misfit, FRESH).terminated
    paper = session_preset("paper")
    assert stop_rule(paper, paper.eps, paper.eps, False, False, misfit, after_novel).terminated


def test_a_covered_known_object_waits_while_its_misfit_count_runs():
    p = session_preset("recommended")
    counting = FRESH._replace(misfit_steps=1)
    assert not stop_rule(p, p.eps, p.eps, False, False, UNDECIDED, counting).terminated
    assert stop_rule(p, p.eps, p.eps, False, False, UNDECIDED, FRESH).terminated
    # A novel stop waits for its checks, not for a count kept through it.
    passed = counting._replace(checks_passed=p.check_lines)
    assert stop_rule(p, p.eps, p.eps, True, True, UNDECIDED, passed).terminated
    # The step cap stops whatever runs.
    last = counting._replace(step=p.max_steps_known - 1)
    assert stop_rule(p, p.eps, p.eps, False, False, UNDECIDED, last).terminated


def test_a_decision_is_confirmed_before_it_stops_a_session():
    p = session_preset("recognise")
    around = p.decision_cover
    stop = stop_rule(p, 10 * p.eps, around, False, False, _decided(), FRESH)
    assert stop.confirm and not stop.decided and not stop.terminated
    confirmed = FRESH._replace(decision_checks=p.decision_checks)
    stop = stop_rule(p, 10 * p.eps, around, False, False, _decided(), confirmed)
    assert stop.decided and stop.terminated and stop.decision_checks == p.decision_checks
    # Contacts not yet all around the MAP: not decided, and the count starts again.
    assert decision_ready(p, _decided(), 1.01 * around, p.decision_checks) == (False, False, 0)


def test_rivals_hold_the_covered_stop_for_a_patience_at_most():
    p = session_preset("recommended")
    rivalled = Decision(False, 0.6, (_hypothesis(0.6), _hypothesis(0.4)), fits=True)
    stop = stop_rule(p, p.eps, p.eps, False, False, rivalled, FRESH)
    assert stop.rivals and not stop.terminated
    tired = FRESH._replace(telling_steps=p.decision_patience)
    assert stop_rule(p, p.eps, p.eps, False, False, rivalled, tired).terminated
    # A MAP that fits nothing within the noise has no rivals to tell apart.
    misfit = Decision(False, 0.6, rivalled.hypotheses, fits=False)
    assert stop_rule(p, p.eps, p.eps, False, False, misfit, FRESH).terminated


def test_every_extension_is_off_in_the_paper_preset():
    # planner.EXTENSIONS lists each rule beyond the paper once, with the parameter and the
    # value that switch it off; the paper preset must hold every one of those values.
    from tactile_viz.engine.session.planner import EXTENSIONS

    paper, default = session_preset("paper"), session_preset("recommended")
    switched = [off for _, off in EXTENSIONS if off is not None]
    assert switched
    for name, value in switched:
        assert getattr(paper, name) == value, name
    # and the default runs at least one of them (they are the project's, not the paper's)
    assert any(getattr(default, name) != value for name, value in switched)


@pytest.mark.parametrize("noise", [0.0, 1e-9, 0.3, 1e3])
def test_a_known_object_is_covered_within_its_noise_and_a_novel_within_eps(noise):
    """Under position noise a known estimate counts as covered within
    hypot(eps, cover_noise_stds x noise); a novel one, and the paper, within eps."""
    p = session_preset("recommended")
    reach = float(np.hypot(p.eps, p.cover_noise_stds * noise))
    assert reach >= p.eps
    known = stop_rule(p, reach, 0.0, False, False, UNDECIDED, FRESH, noise)
    assert known.terminated
    assert not stop_rule(p, 1.01 * reach, 0.0, False, False, UNDECIDED, FRESH,
                         noise).terminated
    beyond = np.nextafter(p.eps, np.inf) if noise == 0 else 0.5 * (p.eps + reach)
    if beyond > p.eps * (1 + 1e-12):
        assert stop_rule(p, beyond, 0.0, False, False, UNDECIDED, FRESH, noise).terminated
    novel = stop_rule(p, beyond, 0.0, True, False, UNDECIDED, FRESH, noise)
    assert novel.terminated == (beyond <= p.eps)
    paper = session_preset("paper")
    assert paper.cover_noise_stds == 0
    assert stop_rule(paper, paper.eps, 0.0, False, False, UNDECIDED, FRESH, noise).terminated
    assert not stop_rule(paper, 1.01 * paper.eps, 0.0, False, False, UNDECIDED, FRESH,
                         noise).terminated
