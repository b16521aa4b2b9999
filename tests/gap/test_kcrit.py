"""The augmented model's critical gain (grader.gap.kcrit), against python-control's gain margin."""

from __future__ import annotations

import control
import numpy as np
import pytest

from grader.gap.backend import Point
from grader.gap.kcrit import critical_gain
from grader.gap.runs import GapRun
from grader.model import zloop
from grader.model.effects import EffectSet
from grader.model.linear import plant_coeffs
from grader.model.params import Controller, RigParams
from grader.stations import Station


def _instability_run(p: RigParams, duration: float = 2.0) -> GapRun:
    t = np.round(np.arange(0.0, duration, p.sample_time), 9)
    r = np.where(t >= 0.1, 0.2, 0.0)
    return GapRun("instability", "instability", Controller(1.0), t, r, np.zeros(t.size), None, 0.1, 0.1,
                  np.zeros(t.size))


def _margin_with_delay(p: RigParams, samples: int) -> float:
    """Critical P gain of the sampled loop with ``samples`` whole samples of delay: python-control's gain margin of
    Kamp·k_fb·ZOH(b0/(s(s² + a2·s + a1)))·z^-samples."""
    a2, a1, b0 = plant_coeffs(p)
    plant = control.c2d(control.tf([b0], [1.0, a2, a1, 0.0]), p.sample_time, method="zoh")
    loop = p.Kamp * p.k_fb * plant * control.tf([1.0], [1.0] + [0.0] * samples, p.sample_time)
    gm, *_ = control.stability_margins(loop)
    return float(gm)


@pytest.mark.parametrize("samples", [0, 1, 2])
def test_a_whole_sample_delay_lowers_the_critical_gain_as_the_gain_margin_says(station: Station, samples: int) -> None:
    p = station.params()
    effects = EffectSet({"sampling_delay": {"delay": samples * p.sample_time}})
    k = critical_gain(Point(p, effects), _instability_run(p))
    truth = _margin_with_delay(p, samples)
    assert k is not None and 0.99 * truth <= k < 1.02 * truth  # the grid step, and LASTS just below the boundary
    if samples == 0:
        assert truth == pytest.approx(zloop.critical_gain(p), rel=1e-6)


def test_a_model_without_effects_has_its_exact_critical_gain(station: Station) -> None:
    p = station.params()
    assert critical_gain(Point(p), _instability_run(p)) == zloop.critical_gain(p)
