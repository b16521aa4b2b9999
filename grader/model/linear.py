"""The continuous-time linear model with python-control, and its closed forms.

Plant (Merritt valve + cylinder + mass), with g = 4·β/Vt::

    X/I = g·Kq·A/M / ( s·(s² + (B/M + g·Kce)·s + g·(A² + B·Kce)/M) )      [in/mA]

Loop gain ``L = C(s)·Kamp·k_fb·X/I`` with ``k_fb = Kpot`` (volts) or 1 (inches).
For P control the characteristic polynomial is ``s³ + a2 s² + a1 s + a0`` with
``a0 = Kp·Kamp·k_fb·g·Kq·A/M``; Routh–Hurwitz gives the critical gain
``a0 = a2·a1`` and frequency ``ω² = a1``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from grader.errors import ModelError
from grader.model.params import Controller, RigParams

if TYPE_CHECKING:  # python-control loads on first use (it brings matplotlib): the fast paths never need it
    import control as ct


def plant_coeffs(p: RigParams) -> tuple[float, float, float]:
    """(a2 [1/s], a1 [1/s²], b0 [in/(mA·s³)]) of ``X/I = b0 / (s (s² + a2 s + a1))``."""
    g = 4.0 * p.beta_over_Vt
    a2 = p.B / p.M + g * p.Kce
    a1 = g * (p.A**2 + p.B * p.Kce) / p.M
    b0 = g * p.Kq * p.A / p.M
    return a2, a1, b0


def loop_gain_per_kp(p: RigParams) -> float:
    """a0 per unit Kp [1/s³ per Kp unit]: ``Kamp·k_fb·g·Kq·A/M``."""
    return p.Kamp * p.k_fb * plant_coeffs(p)[2]


def char_poly(p: RigParams, c: Controller) -> NDArray[np.float64]:
    """Monic closed-loop characteristic polynomial coefficients, highest power first."""
    a2, a1, b0 = plant_coeffs(p)
    k = p.Kamp * p.k_fb * b0
    poly = np.array([1.0, a2, a1 + k * c.Kd, k * c.Kp])
    if c.Ki:
        poly = np.append(poly, k * c.Ki)
    return poly


def plant_tf(p: RigParams) -> ct.TransferFunction:
    """X/I [in/mA]."""
    import control as ct

    a2, a1, b0 = plant_coeffs(p)
    return ct.tf([b0], [1.0, a2, a1, 0.0])


def controller_tf(c: Controller) -> ct.TransferFunction:
    """C(s) = Kp + Ki/s + Kd·s (ideal derivative: continuous model only)."""
    import control as ct

    return ct.tf([c.Kd, c.Kp, c.Ki], [1.0, 0.0]) if c.Ki else ct.tf([c.Kd, c.Kp], [1.0])


def open_loop_tf(p: RigParams, c: Controller) -> ct.TransferFunction:
    """L(s) = C·Kamp·k_fb·X/I (dimensionless)."""
    import control as ct

    return ct.minreal(controller_tf(c) * p.Kamp * p.k_fb * plant_tf(p), verbose=False)


def closed_loop_tf(p: RigParams, c: Controller) -> ct.TransferFunction:
    """Y/R for a position command R [in]."""
    import control as ct

    return ct.feedback(open_loop_tf(p, c), 1)


def closed_loop_poles(p: RigParams, c: Controller) -> NDArray[np.complex128]:
    """Roots of the characteristic polynomial, sorted by real part then imaginary part."""
    poles = np.roots(char_poly(p, c))
    return poles[np.lexsort((poles.imag, poles.real))]


def critical_gain(p: RigParams) -> tuple[float, float]:
    """(Kp_crit, omega_crit [rad/s]) of the continuous P loop, from Routh–Hurwitz."""
    a2, a1, _ = plant_coeffs(p)
    k = loop_gain_per_kp(p)
    if a2 <= 0:
        raise ModelError("the loop is unstable for every gain (a2 <= 0: no damping or leakage)")
    return a2 * a1 / k, math.sqrt(a1)


def velocity_constant(p: RigParams, kp: float) -> float:
    """Kv = lim s·L(s) [1/s] for P control."""
    a1 = plant_coeffs(p)[1]
    return kp * loop_gain_per_kp(p) / a1


def ramp_error(p: RigParams, kp: float, rate: float) -> float:
    """Steady-state error [in] of P control following a ramp of ``rate`` [in/s]."""
    return rate / velocity_constant(p, kp)


def root_locus(p: RigParams, gains: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Closed-loop P poles for each gain: array of shape (len(gains), 3)."""
    return np.array([closed_loop_poles(p, Controller(Kp=float(k))) for k in gains])
