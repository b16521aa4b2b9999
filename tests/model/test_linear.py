"""The linear model: symbolic, numeric and closed-form paths agree; Routh is right."""

from __future__ import annotations

import control as ct
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.model import linear, sampled, symbolic
from grader.model.params import Controller, RigParams, mass_from_weight, piston_area

BASE = RigParams(A=piston_area(0.5, 0.25), M=mass_from_weight(29.0), Kamp=5.0, Kq=0.0385, Kpot=0.85,
                 beta_over_Vt=22170.0, Kce=7.22e-4)

params = st.builds(
    lambda kq, kpot, bv, kce, b, fb: BASE.with_(Kq=kq, Kpot=kpot, beta_over_Vt=bv, Kce=kce, B=b, feedback=fb),
    st.floats(0.01, 0.1), st.floats(0.2, 3.0), st.floats(5e3, 1e5), st.floats(1e-5, 3e-3), st.floats(0.0, 0.5),
    st.sampled_from(["volts", "inches"]),
)
controllers = st.builds(Controller, st.floats(0.5, 80), st.sampled_from([0.0, 5.0, 40.0]), st.sampled_from([0.0, 0.05]))


def _subs(p: RigParams, c: Controller) -> dict[sp.Symbol, float]:
    S = symbolic
    return {S.A: p.A, S.M: p.M, S.Kamp: p.Kamp, S.Kq: p.Kq, S.Kpot: p.Kpot, S.beta: p.beta_over_Vt, S.Vt: 1.0,
            S.Kce: p.Kce, S.B: p.B, S.Kp: c.Kp, S.Ki: c.Ki, S.Kd: c.Kd}


@settings(max_examples=40, deadline=None)
@given(params, controllers)
def test_symbolic_char_poly_matches_closed_form(p: RigParams, c: Controller) -> None:
    coeffs = symbolic.char_poly_coeffs(p.feedback, c.kind)
    numeric = np.array([float(cf.subs(_subs(p, c))) for cf in coeffs])
    np.testing.assert_allclose(numeric, linear.char_poly(p, c), rtol=1e-10)


@settings(max_examples=30, deadline=None)
@given(params, controllers)
def test_python_control_poles_match_char_poly_roots(p: RigParams, c: Controller) -> None:
    poles = np.sort_complex(ct.poles(linear.closed_loop_tf(p, c)))
    expected = np.sort_complex(np.roots(linear.char_poly(p, c)))
    np.testing.assert_allclose(poles, expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())


@settings(max_examples=40, deadline=None)
@given(params)
def test_routh_critical_gain_puts_poles_on_the_imaginary_axis(p: RigParams) -> None:
    kc, w = linear.critical_gain(p)
    poles = linear.closed_loop_poles(p, Controller(Kp=kc))
    pair = poles[np.argmax(np.abs(poles.imag))]
    assert abs(pair.real) < 1e-6 * abs(pair)
    assert abs(abs(pair.imag) - w) < 1e-6 * w
    assert np.max(linear.closed_loop_poles(p, Controller(Kp=0.98 * kc)).real) < 0
    assert np.max(linear.closed_loop_poles(p, Controller(Kp=1.02 * kc)).real) > 0


def test_symbolic_plant_is_merritt_form() -> None:
    S = symbolic
    g = 4 * S.beta / S.Vt
    expected = g * S.Kq * S.A / (S.S * (S.M * S.S**2 + (S.B + S.M * g * S.Kce) * S.S + g * (S.A**2 + S.B * S.Kce)))
    assert sp.simplify(symbolic.reduce_loop().plant - expected) == 0


def test_feedback_conventions_differ_only_by_kpot_in_the_loop() -> None:
    p_in = BASE.with_(feedback="inches")
    np.testing.assert_allclose(linear.char_poly(BASE, Controller(10)), linear.char_poly(p_in, Controller(10 * BASE.Kpot)))


def test_ramp_error_matches_simulation() -> None:
    p = BASE
    t = np.arange(0, 3.0, p.sample_time)
    r = 1.0 * t
    res = sampled.simulate(p, Controller(10), t, r)
    assert (r - res.y)[-1] == pytest.approx(linear.ramp_error(p, 10, 1.0), rel=0.01)


def test_sampled_loop_converges_to_continuous_as_T_shrinks() -> None:
    t = np.arange(0, 1.0, 1e-4)
    r = np.where(t > 0.05, 0.2, 0.0)
    cont = ct.forced_response(linear.closed_loop_tf(BASE, Controller(25)), T=t, U=r).outputs
    errs = [np.max(np.abs(sampled.simulate(BASE.with_(sample_time=T), Controller(25), t, r).y - cont)) for T in (1e-3, 1e-4)]
    assert errs[1] < errs[0] / 5
    assert errs[1] < 2e-3 * 0.2


def test_discrete_critical_gain_is_below_continuous_and_close() -> None:
    k_cont, _ = linear.critical_gain(BASE)
    k_disc = sampled.discrete_critical_gain(BASE)
    assert 0.9 * k_cont < k_disc < k_cont
    assert max(abs(sampled.discrete_poles(BASE, Controller(k_disc * 0.999)))) < 1
    assert max(abs(sampled.discrete_poles(BASE, Controller(k_disc * 1.001)))) > 1


def test_default_station_behaves_as_the_paper_describes(station) -> None:  # noqa: ANN001
    from grader.model import zloop

    p = station.params()
    k_crit = zloop.critical_gain(p)
    assert zloop.overshoot(p, Controller(10)) < 1e-4  # Kp = 10 looks first order
    poles25 = linear.closed_loop_poles(p, Controller(25))
    real25 = poles25[np.abs(poles25.imag) < 1e-9][0].real
    pair25 = poles25[poles25.imag > 0][0]
    assert abs(pair25.real) < 2 * abs(real25)  # the complex pair is visible at Kp = 25: third order
    pair46 = linear.closed_loop_poles(p, Controller(46))
    pair46 = pair46[pair46.imag > 0][0]
    assert -pair46.real / abs(pair46) < 0.05  # lightly damped pair dominates at 46
    assert zloop.gain_for_overshoot(p, 0.25) < k_crit  # 25 % overshoot reachable
    assert 50 < k_crit < 65


def test_root_locus_rows_are_the_closed_loop_poles_and_cross_at_the_critical_gain() -> None:
    kc, w = linear.critical_gain(BASE)
    gains = np.array([1.0, 10.0, kc, 2 * kc])
    locus = linear.root_locus(BASE, gains)
    assert locus.shape == (4, 3)
    np.testing.assert_allclose(locus[1], linear.closed_loop_poles(BASE, Controller(10.0)))
    assert np.max(locus[0].real) < 0 and np.max(locus[3].real) > 0
    assert np.min(np.abs(locus[2].imag - w)) < 1e-6 * w
