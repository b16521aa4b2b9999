"""Design checks: on the model (goal, claim, stability) and the rig verdict classifier."""

from __future__ import annotations

import numpy as np
import pytest

from grader.grading.answers import DesignAnswer, Gains
from grader.grading.context import KeyContext
from grader.grading.designs import RigCase, classify, evaluate_design, rig_verdicts
from grader.grading.rubric import DesignSpec

SPEC = DesignSpec()


def test_classify_synthetic_signals() -> None:
    t = np.arange(0, 3, 0.001)
    r = np.where(t > 0.1, 0.2, 0.0)
    settled = r - 0.2 * np.exp(-20 * np.maximum(t - 0.1, 0)) * (t > 0.1)
    hunting = settled + 0.01 * np.sin(2 * np.pi * 3 * t)
    u = np.zeros_like(t)
    assert classify(r, settled, u, threshold=0.002) == "ok"
    assert classify(r, hunting, u, threshold=0.002) == "limit_cycle"
    assert classify(r, hunting, np.where(np.sin(2 * np.pi * 3 * t) > 0, 10.0, -10.0), threshold=0.002) == "unstable"
    assert classify(r, np.full_like(t, np.nan), u, threshold=0.002) == "unstable"
    assert classify(r, r + 50.0, u, threshold=0.002) == "unstable"


def test_pd_goal_needs_a_derivative_that_cuts_overshoot(kc: KeyContext) -> None:
    p = kc.params()
    good = evaluate_design("pd_design", DesignAnswer(Gains(46, 0, 0.2), 0.14), p, SPEC, ramp_rate=1.0)
    assert good.stable and good.goal_met and good.achieved < 0.8 * good.baseline and good.claim_ok
    none = evaluate_design("pd_design", DesignAnswer(Gains(46), None), p, SPEC, ramp_rate=1.0)
    assert none.stable and not none.goal_met and none.claim_ok is None
    wild = evaluate_design("pd_design", DesignAnswer(Gains(30, 0, 3.0), 0.1), p, SPEC, ramp_rate=1.0)
    assert not wild.stable and not wild.goal_met and wild.claim_ok is None


def test_pi_goal_removes_the_ramp_error(kc: KeyContext) -> None:
    p = kc.params()
    good = evaluate_design("pi_design", DesignAnswer(Gains(10, 20), 0.0), p, SPEC, ramp_rate=1.0)
    assert good.goal_met and abs(good.achieved) < 1e-3 and good.baseline == pytest.approx(kc.value("ramp_ess_P"), rel=0.01)
    slow = evaluate_design("pi_design", DesignAnswer(Gains(10, 0.5), 0.0), p, SPEC, ramp_rate=1.0)
    assert slow.stable and not slow.goal_met and slow.claim_ok is False


def test_rig_verdicts_are_batched_and_deterministic() -> None:
    cases = [RigCase("default", "pd_design", Gains(46, 0, 0.2)), RigCase("default", "pi_design", Gains(5, 400)),
             RigCase("nowhere", "pd_design", Gains(46, 0, 0.2))]
    first = rig_verdicts(cases, threshold=0.002)
    assert first == {cases[0]: "ok", cases[1]: "limit_cycle", cases[2]: None}
    assert rig_verdicts(cases[:2], threshold=0.002) == {c: first[c] for c in cases[:2]}
