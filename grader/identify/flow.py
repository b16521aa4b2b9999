"""No-load valve flow gain Kq [in³/s/mA] from the bypass flow test.

The flow meter reads magnitude only and includes the valve's constant internal
leakage. The procedure: find the null (the minimum reading), subtract the
leakage, give each reading its direction, convert input volts to current with
Kamp, keep the linear region (saturation excluded), and fit
``reading = |Kq·(i − i0)| + leakage`` there by least squares.

The linear region grows outward from a core round the null: the central half of the
currents, or less when the flow saturates early (a valve whose current limit is a
fraction of the amplifier's range): the core then ends short of where a V clipped at
the plateau, fitted to every reading, saturates.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import OptimizeResult, least_squares

from grader.errors import IdentificationError
from grader.identify.estimate import Estimate


def _fit_v(i: NDArray[np.float64], q: NDArray[np.float64], x0: NDArray[np.float64]) -> OptimizeResult:
    """Least squares for ``q = |Kq·(i − i0)| + leakage``; x = (Kq, i0, leakage)."""
    return least_squares(lambda x: np.abs(x[0] * (i - x[1])) + x[2] - q, x0, method="lm")


#: The core ends at this share of the current where the clipped V saturates; at least CORE_MIN points each side.
CORE_SHARE, CORE_MIN = 0.9, 2


def _saturation_current(i: NDArray[np.float64], q: NDArray[np.float64], x0: NDArray[np.float64]) -> float:
    """|i − i0| [mA] at which ``q = min(|Kq·(i − i0)|, Qs) + leakage``, fitted to every reading, saturates."""
    qs0 = float(np.max(q) - x0[2])
    fit = least_squares(lambda x: np.minimum(np.abs(x[0] * (i - x[1])), x[3]) + x[2] - q,
                        np.array([*x0, qs0]), method="trf", x_scale="jac")
    kq, qs = abs(float(fit.x[0])), float(fit.x[3])
    return qs / kq if kq > 0 and qs > 0 else float("inf")


def _core(d: NDArray[np.float64], d_sat: float) -> NDArray[np.bool_]:
    """The central half of the currents, cut short of saturation, with at least CORE_MIN points each side."""
    keep = np.abs(d) <= min(0.5 * np.max(np.abs(d)), CORE_SHARE * d_sat)
    for side in (1.0, -1.0):
        own = np.flatnonzero(np.sign(d) == side)
        keep[own[np.argsort(np.abs(d[own]))[:CORE_MIN]]] = True
    return keep


def _linear_region(i: NDArray[np.float64], q: NDArray[np.float64], x0: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Points on the V: start from the core (:func:`_core`) and grow each side outward until a
    point leaves the fitted V by more than 4 σ or 1 % (saturation begins there)."""
    d = i - x0[1]
    keep = _core(d, _saturation_current(i, q, x0))
    for side in (1.0, -1.0):
        outer = np.flatnonzero((np.sign(d) == side) & ~keep)
        for k in outer[np.argsort(np.abs(d[outer]))]:
            fit = _fit_v(i[keep], q[keep], x0)
            sd = float(np.std(fit.fun, ddof=3)) if keep.sum() > 3 else 0.0
            pred = abs(fit.x[0] * (i[k] - fit.x[1])) + fit.x[2]
            if abs(q[k] - pred) > max(4.0 * sd, 0.01 * pred):
                break
            keep[k] = True
    return keep


class FlowGainFit:
    """Fit Kq from amplifier input volts and flow-meter readings [in³/s].

    Config: ``Kamp`` [mA/V]. Learned: ``Kq_`` [in³/s/mA], ``leakage_`` [in³/s],
    ``null_current_`` [mA] (Estimates), ``linear_mask_`` (points used). A leakage fitted
    below 0 is clipped to 0 with a note.
    """

    def __init__(self, *, Kamp: float) -> None:
        self.Kamp = Kamp

    def fit(self, input_volts: ArrayLike, reading: ArrayLike) -> FlowGainFit:
        v, q = np.asarray(input_volts, float), np.asarray(reading, float)
        if v.size < 6 or np.ptp(v) <= 0:
            raise IdentificationError("flow test: need at least 6 readings over a range of inputs")
        if np.any(q < 0):
            raise IdentificationError("flow test: the flow meter reads magnitudes; negative readings found")
        i = self.Kamp * v
        null = int(np.argmin(q))
        side = np.sign(i - i[null])
        if not (np.any(side > 0) and np.any(side < 0)):
            raise IdentificationError("flow test: readings must span both sides of the valve null")
        slope0 = np.polyfit(i, side * (q - q[null]), 1)[0]
        x0 = np.array([abs(slope0), i[null], q[null]])
        mask = _linear_region(i, q, x0)
        res = _fit_v(i[mask], q[mask], x0)
        dof = int(mask.sum()) - 3
        s2 = float(res.fun @ res.fun / max(dof, 1))
        cov = s2 * np.linalg.pinv(res.jac.T @ res.jac)
        se = np.sqrt(np.diag(cov))
        note = {"points_used": float(mask.sum()), "points": float(v.size), "Kamp [mA/V]": self.Kamp}
        self.Kq_ = Estimate(float(res.x[0]), "in**3/s/mA", float(se[0]),
                            "|Kq·(i−i0)| + leakage fitted over the linear region (saturation excluded)", note, dof)
        self.null_current_ = Estimate(float(res.x[1]), "mA", float(se[1]), "null of the same fit", note, dof)
        self.leakage_ = Estimate(float(res.x[2]), "in**3/s", float(se[2]), "constant internal leakage of the same fit",
                                 note, dof).clipped_below(0.0)
        self.linear_mask_ = mask
        return self
