"""Potentiometer gain Kpot [V/in]: regression of voltage on position."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from grader.errors import IdentificationError
from grader.identify.estimate import Estimate


class PotCalibration:
    """Least-squares line ``voltage = offset + Kpot·position``.

    Learned: ``Kpot_`` and ``offset_`` (Estimates), ``residual_sd_`` [V].
    """

    def fit(self, position: ArrayLike, voltage: ArrayLike) -> PotCalibration:
        x, v = np.asarray(position, float), np.asarray(voltage, float)
        if np.ptp(x) <= 0:
            raise IdentificationError("calibration: positions are all equal; move the mass a known distance")
        res = stats.linregress(x, v)
        dof = x.size - 2
        if not abs(res.slope) > (stats.t.ppf(0.975, dof) * res.stderr if dof > 0 else 0.0):
            se = f" ± {res.stderr:.2g}" if np.isfinite(res.stderr) and res.stderr > 0 else ""
            raise IdentificationError(f"calibration: the voltage does not change with position (slope {res.slope:.3g}"
                                      f"{se} V/in); is the pot wired and powered?")
        note = {"points": float(x.size), "span [in]": float(np.ptp(x))}
        self.Kpot_ = Estimate(abs(res.slope), "V/in", res.stderr, "least-squares slope of voltage on position", note, dof)
        self.offset_ = Estimate(res.intercept, "V", res.intercept_stderr, "intercept of the same fit", note, dof)
        self.residual_sd_ = float(np.std(v - (res.intercept + res.slope * x), ddof=2)) if dof > 0 else 0.0
        return self
