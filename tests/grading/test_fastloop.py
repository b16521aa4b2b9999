"""The fast polynomial sampled loop agrees with grader.model.sampled (an independent path)."""

from __future__ import annotations

import numpy as np
import pytest

from grader.grading import fastloop
from grader.grading.answers import Gains
from grader.identify.predict import gain_for_overshoot, gain_no_overshoot
from grader.model.params import Controller, RigParams
from grader.model.sampled import discrete_critical_gain, discrete_poles, simulate
from grader.stations import Station


@pytest.fixture(scope="module")
def p(station: Station) -> RigParams:
    return station.params()


@pytest.mark.parametrize("g", [Gains(10), Gains(46), Gains(30, 0, 0.05), Gains(10, 20), Gains(40, 5, 0.02), Gains(56)])
def test_response_matches_the_reference_loop(p: RigParams, g: Gains) -> None:
    t = np.arange(0, 1.5, p.sample_time)
    r = np.where(t > 0, 0.2, 0.0) + np.where(t > 0.5, 0.3 * (t - 0.5), 0.0)
    ref = simulate(p, Controller(g.Kp, g.Ki, g.Kd), t, r).y
    assert np.max(np.abs(fastloop.response(p, g, r) - ref)) < 1e-8


@pytest.mark.parametrize("g", [Gains(10), Gains(56), Gains(57), Gains(30, 0, 2.5), Gains(10, 2000), Gains(10, 5000)])
def test_stability_matches_the_reference_poles(p: RigParams, g: Gains) -> None:
    assert fastloop.is_stable(p, g) == bool(max(abs(discrete_poles(p, Controller(g.Kp, g.Ki, g.Kd)))) < 1)


def test_gains_match_the_reference_predictions(p: RigParams) -> None:
    assert fastloop.critical_gain(p) == pytest.approx(discrete_critical_gain(p), rel=1e-6)
    assert fastloop.gain_no_overshoot(p) == pytest.approx(gain_no_overshoot(p), rel=1e-4)
    assert fastloop.gain_for_overshoot(p, 0.25) == pytest.approx(gain_for_overshoot(p, 0.25), rel=1e-4)


def test_ramp_error_of_p_control_is_rate_over_kv(p: RigParams) -> None:
    from grader.model.linear import ramp_error

    assert fastloop.ramp_error(p, Gains(10), 1.0, 3.0) == pytest.approx(ramp_error(p, 10, 1.0), rel=1e-3)
    assert abs(fastloop.ramp_error(p, Gains(10, 20), 1.0, 4.0)) < 1e-4
    assert fastloop.ramp_error(p, Gains(10, 5000), 1.0, 4.0) == float("inf")
