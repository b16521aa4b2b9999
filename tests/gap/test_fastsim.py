"""The fitting simulator reproduces the rig simulator sample for sample, and the linear loop exactly."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import linalg

from grader.gap import fastsim
from grader.model import zloop
from grader.model.effects import EffectSet
from grader.model.params import Controller
from grader.model.rig import simulate_rig
from grader.model.sampled import discrete_critical_gain, simulate
from grader.stations import Station

T_END = 0.5
CASES = [
    ("coulomb_friction:Fc=2lbf", Controller(25)),
    ("viscous_friction:B=0.3lbf*s/in", Controller(46)),
    ("valve_saturation:i_max=25mA", Controller(46)),
    ("valve_hysteresis:width=1.5mA", Controller(10, Ki=20)),
    ("valve_deadband:width=1mA", Controller(25)),
    ("pressure_flow_nonlinearity", Controller(46)),
    ("sampling_delay:delay=1.5ms", Controller(46)),
    ("sampling_delay:delay=2ms", Controller(25, Kd=0.05)),
    ("valve_dynamics:tau=2ms", Controller(46)),
]


def _step(T: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.round(np.arange(0.0, T_END + 1e-9, T), 9)
    return t, np.where(t >= 0.05, 0.2, 0.0)


@pytest.mark.parametrize(("effect", "controller"), CASES)
def test_matches_rig_simulator_sample_for_sample(station: Station, effect: str, controller: Controller) -> None:
    p = station.params()
    t, r = _step(p.sample_time)
    effects = EffectSet.parse([effect])
    y_rig, _ = simulate_rig(p, controller, t, r, effects)
    (y_fast,) = fastsim.simulate([p], [controller], [effects], [r])
    # the rig integrates with RK4 substeps: agreement to a small fraction of the 0.4 mil noise
    assert np.max(np.abs(y_fast - y_rig)) < 3e-5


def test_without_effects_is_the_exact_linear_loop(station: Station) -> None:
    p = station.params()
    t, r = _step(p.sample_time)
    for c in (Controller(10), Controller(46), Controller(10, Ki=20, Kd=0.02)):
        (y,) = fastsim.simulate([p], [c], [EffectSet()], [r])
        assert np.max(np.abs(y - simulate(p, c, t, r).y)) < 1e-9


def test_linear_filter_is_the_sampled_loop(station: Station) -> None:
    p = station.params()
    t, r = _step(p.sample_time)
    for c in (Controller(25), Controller(10, Ki=20, Kd=0.02)):
        np.testing.assert_allclose(zloop.response(p, c, r), simulate(p, c, t, r).y, rtol=0, atol=1e-9)


def test_batch_of_mixed_runs_equals_runs_alone(station: Station) -> None:
    p = station.params()
    r = _step(p.sample_time)[1]
    sets = [EffectSet.parse([e]) for e, _ in CASES[:6]]
    cmds = [r, r[:300], 0.5 * r, r, r[:200], r]
    together = fastsim.simulate([p] * 6, [c for _, c in CASES[:6]], sets, cmds)
    for (_, c), e, cmd, y in zip(CASES[:6], sets, cmds, together):
        np.testing.assert_allclose(y, fastsim.simulate([p], [c], [e], [cmd])[0], rtol=0, atol=1e-12)


def test_controller_reads_the_given_noise(station: Station) -> None:
    p = station.params()
    t, r = _step(p.sample_time)
    noise = np.full(t.size, 0.01)  # a constant reading offset: the loop settles 0.01 in low
    (y,) = fastsim.simulate([p], [Controller(25)], [EffectSet()], [r], [noise])
    assert y[-1] == pytest.approx(0.19, abs=2e-3)


def test_unsupported_combination_is_refused(station: Station) -> None:
    assert not fastsim.supports(EffectSet.parse(["valve_dynamics:tau=1ms", "valve_deadband:width=1mA"]))
    assert not fastsim.supports(EffectSet.parse(["sensor_quantization:bits=12"]))
    assert fastsim.supports(EffectSet.parse(["valve_saturation:i_max=30mA", "sampling_delay:delay=1ms"]))


@settings(max_examples=25, deadline=None)
@given(st.floats(0.1, 30.0), st.integers(1, 40))
def test_expm_batch_matches_scipy(scale: float, seed: int) -> None:
    m = np.random.default_rng(seed).normal(size=(4, 7, 7)) * scale
    np.testing.assert_allclose(fastsim.expm_batch(m), linalg.expm(m), rtol=1e-9, atol=1e-9 * np.abs(linalg.expm(m)).max())


@settings(max_examples=8, deadline=None)
@given(st.floats(1e4, 4e4), st.floats(2e-4, 2e-3), st.floats(0.5, 2.0))
def test_fast_critical_gain_matches_python_control(station: Station, bv: float, kce: float, kpot: float) -> None:
    p = station.params().with_(beta_over_Vt=bv, Kce=kce, Kpot=kpot)
    assert zloop.critical_gain(p) == pytest.approx(discrete_critical_gain(p), rel=1e-6)
