"""The linear digital loop as a fast filter, for fitting.

Same loop as :func:`grader.model.sampled.simulate` (controller sampled every T with
zero-order hold, plant discretised exactly, no hardware limits), but the closed loop
Y/R is built as polynomials in z and run with :func:`scipy.signal.lfilter`, so one run
of 2000 samples costs well under a millisecond. Inputs and outputs are on the
controller's sample grid: r_k, y_k [in]. Also the sampled loop's critical gain, by
bisection on the roots of its characteristic polynomial (a few milliseconds).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import linalg, signal

from grader.errors import ModelError
from grader.model.linear import plant_coeffs
from grader.model.params import Controller, RigParams

Array = NDArray[np.float64]


def plant_zoh(p: RigParams) -> tuple[Array, Array]:
    """(num, den) in z of the ZOH-discretised plant X/I [in/mA] at ``p.sample_time``."""
    a2, a1, b0 = plant_coeffs(p)
    T = p.sample_time
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -a1, -a2]])
    big = np.zeros((4, 4))
    big[:3, :3], big[2, 3] = a * T, b0 * T
    e = linalg.expm(big)
    num, den = signal.ss2tf(e[:3, :3], e[:3, 3:], np.array([[1.0, 0.0, 0.0]]), np.zeros((1, 1)))
    return np.atleast_1d(num.squeeze()), den


def controller_z(c: Controller, T: float) -> tuple[Array, Array]:
    """(num, den) in z of C(z) = Kp + Ki·T·z/(z−1) + Kd·(z−1)/(T·z), over the common z(z−1)."""
    z_zm1 = np.array([1.0, -1.0, 0.0])
    num = c.Kp * z_zm1 + c.Ki * T * np.array([1.0, 0.0, 0.0]) + (c.Kd / T) * np.array([1.0, -2.0, 1.0])
    return num, z_zm1


def closed_loop_z(p: RigParams, c: Controller) -> tuple[Array, Array]:
    """(b, a) of Y/R for :func:`scipy.signal.lfilter`, normalised so a[0] = 1."""
    gn, gd = plant_zoh(p)
    cn, cd = controller_z(c, p.sample_time)
    open_num = np.polymul(cn, gn) * (p.Kamp * p.k_fb)
    den = np.polyadd(np.polymul(cd, gd), open_num)
    num = np.concatenate([np.zeros(den.size - open_num.size), open_num])
    return num / den[0], den / den[0]


def simulate_grid(p: RigParams, c: Controller, r_k: Array) -> Array:
    """y_k [in] of the loop at rest at y = r_0 for the sampled command ``r_k`` [in]."""
    b, a = closed_loop_z(p, c)
    return signal.lfilter(b, a, r_k - r_k[0]) + r_k[0]


def critical_gain(p: RigParams, *, rel_tol: float = 1e-9) -> float:
    """Smallest P gain at which the sampled loop's poles reach the unit circle (bisection on the
    roots of its characteristic polynomial, as :func:`grader.model.sampled.discrete_critical_gain`)."""
    gn, gd = plant_zoh(p)
    base, per_kp = gd, gn * (p.Kamp * p.k_fb)

    def stable(k: float) -> bool:
        return bool(np.max(np.abs(np.roots(np.polyadd(base, k * per_kp)))) < 1.0)

    lo, hi = 0.0, 1.0
    while stable(hi):
        lo, hi = hi, 2.0 * hi
        if hi > 1e12:
            raise ModelError("the sampled loop has no finite critical gain")
    while hi - lo > rel_tol * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return 0.5 * (lo + hi)
