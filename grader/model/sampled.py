"""The digital loop as the rig runs it: controller sampled every ``sample_time``
with zero-order hold on the plant input.

At sample k the controller reads ``y_k``, forms ``e_k = k_fb·(r_k − y_k)`` and
outputs ``u_k = Kp·e_k + Ki·T·Σ_{j≤k} e_j + Kd·(e_k − e_{k−1})/T`` [V], held until
the next sample; the amplifier drives ``i = Kamp·u`` [mA] into the valve.
The plant is discretised exactly (ZOH) with python-control.
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np
from numpy.typing import NDArray

from grader.errors import ModelError
from grader.model.linear import plant_tf
from grader.model.params import Controller, RigParams


@dataclass(frozen=True)
class SampledResponse:
    """A simulated run on the run's own time base: y [in], u [V]."""

    t: NDArray[np.float64]
    y: NDArray[np.float64]
    u: NDArray[np.float64]


def discrete_controller(c: Controller, T: float) -> ct.TransferFunction:
    """C(z) with backward-Euler integral and backward-difference derivative."""
    z = ct.tf([1.0, 0.0], [1.0], T)
    cz = c.Kp + 0 * z
    if c.Ki:
        cz = cz + c.Ki * T * z / (z - 1)
    if c.Kd:
        cz = cz + c.Kd * (z - 1) / (T * z)
    return ct.minreal(cz, verbose=False)


def discrete_loop(p: RigParams, c: Controller) -> tuple[ct.TransferFunction, ct.TransferFunction]:
    """(Y/R, U/R) of the sampled loop; R and Y in in, U in V."""
    if p.sample_time <= 0:
        raise ModelError("the sampled loop needs sample_time > 0")
    gz = ct.sample_system(plant_tf(p), p.sample_time, method="zoh") * p.Kamp
    cz = discrete_controller(c, p.sample_time) * p.k_fb
    y_r = ct.feedback(cz * gz, 1)
    u_r = ct.feedback(cz, gz)
    return y_r, u_r


def simulate(p: RigParams, c: Controller, t: NDArray[np.float64], r: NDArray[np.float64]) -> SampledResponse:
    """Simulate the sampled loop for command ``r(t)`` [in]; the loop starts at rest at y = r[0].

    ``t`` need not be on the sample grid: r is sampled (held) at the controller's
    instants and y is interpolated back onto ``t``.
    """
    T = p.sample_time
    t = np.asarray(t, dtype=float)
    r = np.asarray(r, dtype=float)
    n = int(np.floor((t[-1] - t[0]) / T + 1e-9)) + 1
    grid = t[0] + T * np.arange(n)
    idx = np.clip(np.searchsorted(t, grid + 1e-12 * T, side="right") - 1, 0, len(t) - 1)
    r_k = r[idx] - r[0]
    y_r, u_r = discrete_loop(p, c)
    y_k = ct.forced_response(y_r, T=grid - grid[0], U=r_k).outputs + r[0]
    u_k = ct.forced_response(u_r, T=grid - grid[0], U=r_k).outputs
    y = np.interp(t, grid, y_k)
    u = u_k[np.clip(np.searchsorted(grid, t + 1e-12 * T, side="right") - 1, 0, n - 1)]
    return SampledResponse(t=t, y=y, u=u)


def discrete_poles(p: RigParams, c: Controller) -> NDArray[np.complex128]:
    """Closed-loop poles of the sampled loop (z-plane)."""
    return np.asarray(ct.poles(discrete_loop(p, c)[0]))


def discrete_critical_gain(p: RigParams, *, hi: float | None = None) -> float:
    """Smallest P gain at which the sampled loop reaches the unit circle (bisection)."""
    from grader.model.linear import critical_gain

    k_cont = critical_gain(p)[0]
    lo, hi = 0.0, hi or k_cont
    while max(abs(discrete_poles(p, Controller(Kp=hi)))) < 1.0:
        lo, hi = hi, 2 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if max(abs(discrete_poles(p, Controller(Kp=mid)))) < 1.0:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-9 * hi:
            break
    return 0.5 * (lo + hi)
