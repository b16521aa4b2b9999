"""β/Vt and Kce from the limit of stability.

**Students' procedure (the key).** At the limit of stability the P loop's
characteristic polynomial is ``(s + a)(s² + ω²)``; equating coefficients with
``s³ + (B/M + g·Kce)s² + g(A² + B·Kce)/M·s + g·Kc·Kq·A/M`` (g = 4β/Vt,
Kc = Kp_crit·Kamp·k_fb) gives, for any B,

    u = g·Kce = ω²(M·c − B/M)/(ω² + B·c),  c = Kc·Kq/(A·M)
    g = (M·ω² − B·u)/A²

**Model refinement.** The rig's loop is digital and the instability run sits a
little past the limit, so the identified *model* instead places the sampled
loop's complex pole pair at the measured ``σ ± jω`` at the run's gain.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from grader.errors import IdentificationError
from grader.model.params import Controller, RigParams
from grader.model import zloop


def coefficient_match(*, omega: float, kp_crit: float, A: float, M: float, Kamp: float, Kq: float,
                      k_fb: float, B: float = 0.0) -> tuple[float, float]:
    """(beta_over_Vt [psi/in³], Kce [in³/s/psi]) from ω [rad/s] at the critical gain."""
    if omega <= 0 or kp_crit <= 0:
        raise IdentificationError("critical frequency and gain must be positive")
    c = kp_crit * Kamp * k_fb * Kq / (A * M)
    u = omega**2 * (M * c - B / M) / (omega**2 + B * c)
    g = (M * omega**2 - B * u) / A**2
    if g <= 0 or u < 0:
        raise IdentificationError("coefficient matching gives a negative β/Vt or Kce: check ω, Kp_crit and B")
    return g / 4.0, u / g


def match_sampled_poles(p0: RigParams, *, kp: float, sigma: float, omega: float) -> RigParams:
    """Adjust (β/Vt, Kce) of ``p0`` so the sampled P loop at ``kp`` has poles at σ ± jω."""
    T = p0.sample_time
    target = np.exp(complex(sigma, omega) * T)

    def resid(x: np.ndarray) -> np.ndarray:
        p = p0.with_(beta_over_Vt=float(np.exp(x[0])), Kce=float(np.exp(x[1])))
        z = np.roots(zloop.closed_loop(p, Controller(Kp=kp))[1])
        zc = z[np.argmin(np.abs(z - target))]
        return np.array([(np.log(abs(zc)) - sigma * T) / T / omega, (np.angle(zc) - omega * T) / T / omega]) * 100

    x0 = np.log([p0.beta_over_Vt, max(p0.Kce, 1e-9)])
    res = least_squares(resid, x0, method="lm", xtol=1e-12, ftol=1e-12, x_scale="jac")
    if np.max(np.abs(res.fun)) > 1e-3:
        raise IdentificationError("could not place the sampled loop's poles at the measured oscillation")
    return p0.with_(beta_over_Vt=float(np.exp(res.x[0])), Kce=float(np.exp(res.x[1])))
