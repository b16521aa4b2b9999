"""The fast polynomial sampled loop (zloop) agrees with grader.model.sampled (an independent path)."""

from __future__ import annotations

import numpy as np
import pytest

import control as ct
from scipy.optimize import brentq

from grader.grading.answers import Gains
from grader.model import zloop
from grader.model.params import Controller, RigParams
from grader.model.sampled import discrete_loop, discrete_poles, simulate
from grader.stations import Station


def _reference_critical_gain(p: RigParams) -> float:
    """Bisection on python-control's discrete poles (the independent path)."""
    lo, hi = 1.0, 200.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if max(abs(discrete_poles(p, Controller(mid)))) < 1 else (lo, mid)
    return 0.5 * (lo + hi)


def _reference_gain_for_overshoot(p: RigParams, target: float) -> float:
    def over(k: float) -> float:
        y = ct.step_response(discrete_loop(p, Controller(k))[0], T=np.arange(4000) * p.sample_time).outputs
        return float(max(y.max() - 1.0, 0.0)) - target

    return float(brentq(over, 1.0, 0.995 * _reference_critical_gain(p), xtol=1e-6))


@pytest.fixture(scope="module")
def p(station: Station) -> RigParams:
    return station.params()


@pytest.mark.parametrize("g", [Gains(10), Gains(46), Gains(30, 0, 0.05), Gains(10, 20), Gains(40, 5, 0.02), Gains(56)])
def test_response_matches_the_reference_loop(p: RigParams, g: Gains) -> None:
    t = np.arange(0, 1.5, p.sample_time)
    r = np.where(t > 0, 0.2, 0.0) + np.where(t > 0.5, 0.3 * (t - 0.5), 0.0)
    ref = simulate(p, Controller(g.Kp, g.Ki, g.Kd), t, r).y
    assert np.max(np.abs(zloop.response(p, g, r) - ref)) < 1e-8


@pytest.mark.parametrize("g", [Gains(10), Gains(56), Gains(57), Gains(30, 0, 2.5), Gains(10, 2000), Gains(10, 5000)])
def test_stability_matches_the_reference_poles(p: RigParams, g: Gains) -> None:
    assert zloop.is_stable(p, g) == bool(max(abs(discrete_poles(p, Controller(g.Kp, g.Ki, g.Kd)))) < 1)


def test_gains_match_the_reference_predictions(p: RigParams) -> None:
    assert zloop.critical_gain(p) == pytest.approx(_reference_critical_gain(p), rel=1e-6)
    assert zloop.gain_no_overshoot(p) == pytest.approx(_reference_gain_for_overshoot(p, zloop.NO_OVERSHOOT), rel=1e-4)
    assert zloop.gain_for_overshoot(p, 0.25) == pytest.approx(_reference_gain_for_overshoot(p, 0.25), rel=1e-4)


def test_ramp_error_of_p_control_is_rate_over_kv(p: RigParams) -> None:
    from grader.model.linear import ramp_error

    assert zloop.ramp_error(p, Gains(10), 1.0, 3.0) == pytest.approx(ramp_error(p, 10, 1.0), rel=1e-3)
    assert abs(zloop.ramp_error(p, Gains(10, 20), 1.0, 4.0)) < 1e-4
    assert zloop.ramp_error(p, Gains(10, 5000), 1.0, 4.0) == float("inf")

