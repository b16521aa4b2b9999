"""The instability run's oscillation read as physics: Coulomb friction's amplitude decrement, the
valve/DAC saturation amplitude, an oscillation that friction stops, and runs with no critical
oscillation to read (a limit cycle of an ADC count, a stable loop's decaying transient)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from grader.identify import OscillationFit
from grader.identify.oscillation import envelope_factor, sustained
from grader.identify.pipeline import friction_decrement, saturation_amplitude
from grader.model import zloop
from grader.model.params import Controller
from grader.stations import Station

W, SIGMA, C = 150.0, 2.0, 0.05  # rad/s, 1/s, in/s


def _run(a0: float, *, step: float = 0.2, seed: int = 3, lsb: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A step at 0.1 s, then an oscillation whose envelope obeys da/dt = σ·a − c (integrated
    independently of the fit's closed form), with noise and an optional quantiser."""
    t = np.arange(0.0, 2.0, 0.001)
    sol = solve_ivp(lambda _, a: [SIGMA * a[0] - C if a[0] > 0 else 0.0], (0.1, 2.0), [a0], t_eval=t[t >= 0.1],
                    rtol=1e-10, atol=1e-12)
    env = np.zeros_like(t)
    env[t >= 0.1] = np.maximum(sol.y[0], 0.0)
    y = np.where(t >= 0.1, step, 0.0) + env * np.sin(W * t + 0.3) + np.random.default_rng(seed).normal(0, 2e-4, t.size)
    return t, (np.round(y / lsb) * lsb if lsb else y)


@pytest.mark.parametrize(("a0", "what"), [(0.04, "grows"), (0.022, "friction stops it")])
def test_growth_rate_is_the_linear_loops_once_friction_is_taken_out(a0: float, what: str) -> None:
    t, y = _run(a0)
    with_c = OscillationFit(a_sat=0.5).fit(t, y, start=0.1, decrement=C)
    without = OscillationFit(a_sat=0.5).fit(t, y, start=0.1)
    assert with_c.usable_ and with_c.omega_.value == pytest.approx(W, rel=2e-3)
    assert with_c.sigma_.value == pytest.approx(SIGMA, abs=0.15), what
    assert without.sigma_.value < SIGMA - 0.25  # friction read as less growth: the bias this removes


def test_window_ends_before_saturation() -> None:
    t, y = _run(0.04)
    fit = OscillationFit(a_sat=0.1).fit(t, y, start=0.1, decrement=C)
    grown = np.flatnonzero(envelope_factor(SIGMA, C, 0.04, t[t >= 0.1] - 0.1) * 0.04 >= 0.08)
    assert fit.window_[1] <= t[t >= 0.1][grown[0]] + 0.02


@pytest.mark.parametrize(("a0", "lsb"), [(0.01, 0.0), (0.0015, 0.002)])
def test_no_critical_oscillation_is_not_usable(a0: float, lsb: float) -> None:
    """A transient friction kills within a few cycles; an oscillation below one ADC count."""
    t, y = _run(a0, lsb=lsb)
    fit = OscillationFit().fit(t, y, start=0.1, decrement=C)
    assert not fit.usable_ and "fewer than 8" in (fit.why_not_ or "")


def test_friction_decrement_matches_the_loops_damping_sensitivity(station: Station) -> None:
    """c = −∂σ/∂B · 4Fc/(πω): a viscous B of 4Fc/(π·a·ω) lowers the sampled loop's growth rate by c/a."""
    p = station.params()
    kp = 1.05 * zloop.critical_gain(p)
    w = float((np.log(np.roots(zloop.closed_loop(p, Controller(Kp=kp))[1]).astype(complex)) / p.sample_time).imag.max())
    c = friction_decrement(p, kp, 2.0, w)
    a = 0.05

    def sigma(B: float) -> float:
        s = np.log(np.roots(zloop.closed_loop(p.with_(B=B), Controller(Kp=kp))[1]).astype(complex)) / p.sample_time
        return float(s[np.argmin(np.abs(s - 1j * w))].real)

    assert sigma(p.B) - sigma(p.B + 4 * 2.0 / (np.pi * a * w)) == pytest.approx(c / a, rel=0.05)
    assert saturation_amplitude({"i_max": 50.0, "Kamp": 5.0}, 40.0, 0.8) == pytest.approx(10.0 / 32.0)


@pytest.mark.parametrize("ulps", [1, 3, -2])
def test_friction_decrement_ignores_last_digit_differences(station: Station, ulps: int) -> None:
    """BLAS kernels change the loop's roots in their last digits; a difference quotient magnified that into
    the 7th digit of c, and the growth rate fitted with c moved in its 6th (a key differing between CPUs)."""
    p = station.params()
    kp = 1.05 * zloop.critical_gain(p)
    c = friction_decrement(p, kp, 2.0, 150.0)
    nudged = p.with_(Kq=float(p.Kq + ulps * np.spacing(p.Kq)), beta_over_Vt=float(p.beta_over_Vt - ulps * np.spacing(p.beta_over_Vt)))
    assert c > 0 and friction_decrement(nudged, kp, 2.0, 150.0) == c


def test_an_oscillation_the_run_ends_on_is_not_usable_and_never_a_crash() -> None:
    """An 8-bit ADC's instability run that sits still and starts to swing in its last samples: the free-growth
    window held one reading, and the growing-sinusoid fit on it stopped the diagnosis in SVD. It is now an
    oscillation too short to read."""
    t = np.arange(1137) * 0.00176  # run A's dataset 0227: 8 bits, q = 0.133 in on a 0.2 in step
    q = 0.133
    y = np.where(t >= 0.352, q, 0.0)
    late = np.arange(t.size) >= 1057
    y[late] = q + q * ((np.arange(late.sum()) // 4) % 2 == 0)  # a count's toggle in its last 0.14 s
    fit = OscillationFit().fit(t, y, start=0.10032)
    assert not fit.usable_ and "fewer than 8" in fit.why_not_


def test_an_oscillation_lasts_only_when_it_neither_dies_out_nor_stays_within_a_few_counts() -> None:
    t = np.arange(0.0, 2.0, 0.001)
    ring = np.where(t >= 0.1, np.sin(2 * np.pi * 30 * t), 0.0)
    y = 0.2 + np.stack([0.1 * ring, 0.1 * np.exp(0.1 * t) * ring, 0.1 * np.exp(-0.5 * t) * ring,
                        0.001 * ring])  # lasting, growing, dying out, an ADC count or two
    assert sustained(y, t, 0.1, 0.2).tolist() == [True, True, False, False]
    assert sustained(y[:, :150], t[:150], 1.9, 0.2).tolist() == [False] * 4  # no sample after the command
