"""Friction from force-vs-speed data: ``force = Fc·sign(speed) + B·speed``."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from grader.errors import IdentificationError
from grader.identify.estimate import Estimate


class FrictionFit:
    """Ordinary least squares for Coulomb level ``Fc_`` [lbf] and viscous ``B_`` [lbf·s/in].

    ``B_is_zero_`` is True when B's 95 % interval contains 0 (the model then takes B = 0,
    as the lab concludes). A fit below 0 (noise about a zero B or Fc) is clipped to 0,
    keeping the fit's interval and a note.
    """

    def fit(self, speed: ArrayLike, force: ArrayLike) -> FrictionFit:
        v, f = np.asarray(speed, float), np.asarray(force, float)
        if np.ptp(np.abs(v)) <= 0:
            raise IdentificationError("friction: need at least two different speeds")
        X = np.column_stack([np.sign(v), v])
        coef, *_ = np.linalg.lstsq(X, f, rcond=None)
        dof = v.size - 2
        resid = f - X @ coef
        s2 = float(resid @ resid / dof) if dof > 0 else 0.0
        cov = s2 * np.linalg.inv(X.T @ X)
        note = {"points": float(v.size)}
        Fc = Estimate(float(coef[0]), "lbf", float(np.sqrt(cov[0, 0])), "OLS of force on sign(speed) and speed", note, dof)
        B = Estimate(float(coef[1]), "lbf*s/in", float(np.sqrt(cov[1, 1])), "OLS slope of force on speed", note, dof)
        lo, hi = B.interval
        self.B_is_zero_ = bool(lo <= 0.0 <= hi or B.value <= 0.0)
        self.Fc_, self.B_ = Fc.clipped_below(0.0), B.clipped_below(0.0)
        return self
