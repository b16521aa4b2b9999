"""The sampled loop of :mod:`grader.model.sampled` in a fast polynomial form, for work run
thousands of times (key predictions, design checks, error carried forward).

Same loop: plant ``Kamp·X/I`` discretised with a zero-order hold, controller
``Kp + Ki·T·z/(z−1) + Kd·(z−1)/(T·z)`` on the error scaled by ``k_fb``. Here the
closed loop is a pair of z-polynomials and responses come from :func:`scipy.signal.lfilter`
(tests compare with :func:`grader.model.sampled.simulate`). Results are cached per
(params, gains).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy import signal
from scipy.optimize import brentq

from grader.model.linear import plant_coeffs
from grader.model.params import Controller, Gains, RigParams

Poly = NDArray[np.float64]
STEP_SECONDS = 4.0
#: "No overshoot" means below 0.5 %, the smallest overshoot a student can read off a plot.
NO_OVERSHOOT = 0.005


@lru_cache(maxsize=256)
def plant_z(p: RigParams) -> tuple[Poly, Poly]:
    """(num, den) of ``Kamp·X/I`` in z, ZOH at ``p.sample_time``."""
    a2, a1, b0 = plant_coeffs(p)
    num, den, _ = signal.cont2discrete(([b0 * p.Kamp], [1.0, a2, a1, 0.0]), p.sample_time, method="zoh")
    return _frozen(np.ravel(num).astype(float)), _frozen(np.asarray(den, float))


def _frozen(a: Poly) -> Poly:
    """Cached arrays are shared: make them read-only."""
    a.flags.writeable = False
    return a


def controller_z(g: Gains, T: float) -> tuple[Poly, Poly]:
    """(num, den) of C(z) in lowest terms: the integral brings 1/(z−1), the derivative 1/z."""
    if not g.Ki and not g.Kd:
        return np.array([g.Kp]), np.array([1.0])
    if not g.Ki:
        return np.array([g.Kp + g.Kd / T, -g.Kd / T]), np.array([1.0, 0.0])
    if not g.Kd:
        return np.array([g.Kp + g.Ki * T, -g.Kp]), np.array([1.0, -1.0])
    num = g.Kp * np.array([1.0, -1.0, 0.0]) + g.Ki * T * np.array([1.0, 0.0, 0.0]) + g.Kd / T * np.array([1.0, -2.0, 1.0])
    return num, np.array([1.0, -1.0, 0.0])


@lru_cache(maxsize=4096)
def closed_loop(p: RigParams, g: Gains) -> tuple[Poly, Poly]:
    """(num, den) of Y/R of the sampled loop, of equal length (as :func:`scipy.signal.lfilter`
    reads them, in powers of 1/z); common factors are not cancelled."""
    ng, dg = plant_z(p)
    nc, dc = controller_z(g, p.sample_time)
    forward = p.k_fb * np.polymul(nc, ng)
    den = np.polyadd(np.polymul(dc, dg), forward)
    return _frozen(np.concatenate([np.zeros(den.size - forward.size), forward])), _frozen(den)


@lru_cache(maxsize=8192)
def is_stable(p: RigParams, g: Gains) -> bool:
    """All closed-loop poles strictly inside the unit circle (by a margin of 1e-9)."""
    return bool(np.all(np.abs(np.roots(closed_loop(p, g)[1])) < 1.0 - 1e-9))


def response(p: RigParams, g: Gains, r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Position [in] at each sample for a command ``r`` [in] sampled at ``p.sample_time``."""
    num, den = closed_loop(p, g)
    with np.errstate(all="ignore"):
        y = signal.lfilter(num, den, r)
    return np.where(np.isfinite(y), y, np.inf)


@lru_cache(maxsize=8192)
def overshoot(p: RigParams, g: Gains) -> float:
    """Fractional overshoot of a :data:`STEP_SECONDS` step (inf when the loop is unstable)."""
    if not is_stable(p, g):
        return float("inf")
    y = response(p, g, np.ones(int(STEP_SECONDS / p.sample_time)))
    return float(max(np.max(y) - 1.0, 0.0))


@lru_cache(maxsize=4096)
def ramp_error(p: RigParams, g: Gains, rate: float, seconds: float) -> float:
    """Tracking error r − y [in] at the end of a ramp of ``rate`` [in/s] lasting ``seconds``
    (mean over its last 5 %); inf when the loop is unstable."""
    if not is_stable(p, g):
        return float("inf")
    n = int(seconds / p.sample_time)
    r = rate * p.sample_time * np.arange(n)
    e = r - response(p, g, r)
    return float(np.mean(e[-max(n // 20, 1):]))


@lru_cache(maxsize=512)
def critical_gain(p: RigParams) -> float:
    """Smallest P gain at which the sampled loop reaches the unit circle (bisection)."""
    lo, hi = 0.0, 1.0
    while is_stable(p, Controller(Kp=hi)):
        lo, hi = hi, 2.0 * hi
        if hi > 1e9:
            return float("inf")
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if is_stable(p, Controller(Kp=mid)) else (lo, mid)
        if hi - lo < 1e-9 * hi:
            break
    return 0.5 * (lo + hi)


@lru_cache(maxsize=512)
def gain_for_overshoot(p: RigParams, target: float) -> float | None:
    """P gain whose step overshoots by ``target`` (fraction); None when not reachable."""
    kc = critical_gain(p)
    hi = 0.995 * kc
    f = lambda k: overshoot(p, Controller(Kp=k)) - target  # noqa: E731
    if not np.isfinite(kc) or f(hi) < 0 or f(1e-3 * kc) > 0:
        return None
    return float(brentq(f, 1e-3 * kc, hi, xtol=1e-6 * kc))


def gain_no_overshoot(p: RigParams) -> float | None:
    """Largest P gain with overshoot below :data:`NO_OVERSHOOT`."""
    return gain_for_overshoot(p, NO_OVERSHOOT)
