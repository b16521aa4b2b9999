"""Potentiometer gain Kpot [V/in]: regression of voltage on position."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from grader.errors import IdentificationError
from grader.identify.estimate import Estimate

#: A calibration whose voltage changes over the positions' span by no more than FLAT times the scatter of its
#: readings about the line is flat (a pot not wired or powered), however many readings it has.
FLAT = 2.0


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
        resid_sd = float(np.std(v - (res.intercept + res.slope * x), ddof=2)) if dof > 0 else 0.0
        if not abs(res.slope) * np.ptp(x) > FLAT * resid_sd:  # a flat line: the voltage's change is within its scatter
            raise IdentificationError(f"calibration: the voltage does not change with position (slope {res.slope:.3g} "
                                      f"V/in, scatter {resid_sd:.2g} V); is the pot wired and powered?")
        note = {"points": float(x.size), "span [in]": float(np.ptp(x))}
        self.Kpot_ = Estimate(abs(res.slope), "V/in", res.stderr, "least-squares slope of voltage on position", note, dof)
        self.offset_ = Estimate(res.intercept, "V", res.intercept_stderr, "intercept of the same fit", note, dof)
        self.residual_sd_ = resid_sd
        return self
