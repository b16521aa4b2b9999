"""The diagnosis' BLAS-free arithmetic against the library routines it stands in for."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import savgol_coeffs, savgol_filter

from grader.gap.evidence import _roots
from grader.gap.lm import damped_steps, sumsq
from grader.gap.runs import _DENOMINATOR, _FIT, NOISE_ORDER, NOISE_WINDOW, SMOOTH, quintic_smooth
from grader.model.linear import plant_coeffs
from grader.stations import load_station

from .conftest import seen_without_b


def test_the_smoothing_weights_are_scipys_on_their_exact_grid() -> None:
    assert np.array_equal(_FIT, np.round(_FIT * _DENOMINATOR) / _DENOMINATOR)  # whole multiples of 1/9724
    for k in range(NOISE_WINDOW):
        assert np.allclose(_FIT[k], savgol_coeffs(NOISE_WINDOW, NOISE_ORDER, pos=k, use="dot"), rtol=0, atol=1e-10)
    assert SMOOTH.sum() == pytest.approx(1.0, abs=1e-15)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(NOISE_WINDOW, 400), seed=st.integers(0, 2**31 - 1), trend=st.floats(-5.0, 5.0))
def test_quintic_smooth_is_savgol_filter_with_its_interp_edges(n: int, seed: int, trend: float) -> None:
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)
    y = trend * t**3 + 0.1 * np.sin(20 * t) + 0.01 * rng.standard_normal(n)
    assert np.allclose(quintic_smooth(y), savgol_filter(y, NOISE_WINDOW, NOISE_ORDER), rtol=0, atol=1e-11)


@settings(max_examples=60, deadline=None)
@given(m=st.integers(3, 300), n=st.integers(1, 7), seed=st.integers(0, 2**31 - 1),
       lam=st.floats(1e-6, 1e4))
def test_damped_steps_solve_the_marquardt_equations(m: int, n: int, seed: int, lam: float) -> None:
    rng = np.random.default_rng(seed)
    J = rng.standard_normal((m, n)) * np.exp(rng.uniform(-3, 3, n))
    r = rng.standard_normal(m)
    jtj = J.T @ J
    A = jtj + lam * np.diag(np.diag(jtj) + 1e-12)
    step = damped_steps(J, r, np.array([lam]))[0]
    assert np.allclose(A @ step, -J.T @ r, rtol=1e-8, atol=1e-8 * np.abs(J.T @ r).max())
    assert sumsq(r) == pytest.approx(float(r @ r), rel=1e-12)


@pytest.mark.parametrize("B", [0.0, 0.2, 0.7, 1.5])
def test_the_viscous_b_behind_a_loop_gain_deficit_is_found_exactly(B: float) -> None:
    """The runs see a rig with viscous friction B as a frictionless loop with another g, Kce and Kq; given the
    true Kq, the closed form returns B."""
    true = load_station("default").params().with_(B=B)
    runs = seen_without_b(true)
    assert np.allclose(plant_coeffs(runs), plant_coeffs(true), rtol=1e-12)
    found, _, exact = _roots(runs, true.Kq)
    assert exact and found == pytest.approx(B, abs=1e-9)


def test_quintic_smooth_refuses_fewer_samples_than_its_window() -> None:
    with pytest.raises(ValueError, match=f"at least {NOISE_WINDOW} samples"):
        quintic_smooth(np.zeros(NOISE_WINDOW - 1))


@pytest.mark.parametrize("B", [0.0, 0.4])
def test_a_deficit_larger_than_any_b_explains_gives_the_closest_b_not_exact(B: float) -> None:
    runs = load_station("default").params().with_(B=B)
    a2 = plant_coeffs(runs)[0]
    found, _, exact = _roots(runs, runs.Kq * 1e3)
    assert not exact and found == pytest.approx(a2 * runs.M / 2 - B, rel=1e-12)


def test_an_existing_b_is_added_to() -> None:
    """The runs' model already holding viscous friction B₀ = 0.3 lbf·s/in (and the g, Kce, Kq that give the true
    rig's coefficients with it): given the true Kq, the B returned is what the true B = 0.9 adds to B₀."""
    true = load_station("default").params().with_(B=0.9)
    a2, a1, b0 = plant_coeffs(true)
    M, A, B0 = true.M, true.A, 0.3
    g = (a1 * M - B0 * a2 + B0**2 / M) / A**2
    runs = true.with_(B=B0, beta_over_Vt=g / 4.0, Kce=(a2 - B0 / M) / g, Kq=b0 * M / (g * A))
    assert np.allclose(plant_coeffs(runs), (a2, a1, b0), rtol=1e-12)
    found, _, exact = _roots(runs, true.Kq)
    assert exact and found == pytest.approx(0.9 - B0, abs=1e-9)
