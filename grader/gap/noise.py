"""The measurement noise floor, estimated from the runs themselves.

The reading noise is what a local quintic smoothing (Savitzky–Golay, the window and order
of :mod:`grader.gap.runs`) leaves over: for white noise of RMS σ the residual
of that projection has variance σ²·(1 − c₀), c₀ its centre weight, while the motion
itself, slow at the controller's rate, leaves next to nothing. A 98 % trimmed mean of the
squared residual keeps the step's corner and stick-slip jerks out. A quantising ADC leaves
the readings on a lattice of step q (the position LSB). When the noise dithers the readings
across steps the quantisation error is in that residual too; when it does not, the readings
sit still between steps and the error, up to q/2, is an offset no smoothing sees. The floor
a perfect model could reach is therefore taken as max(σ, q/√12). Both are
*measurement* effects: the diagnosis treats ``sensor_noise`` and ``sensor_quantization``
as the noise floor, not as candidates.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from grader.gap.runs import NOISE_WINDOW, SMOOTH, GapRun, quintic_smooth

Array = NDArray[np.float64]
TRIM = 0.98
#: E[x²] over the smallest 98 % of x² for a unit Gaussian.
TRIMMED_GAUSS = 0.87303
#: A lattice is accepted when at least this share of gaps between distinct readings are whole multiples of q.
LATTICE_SHARE = 0.95


@dataclass(frozen=True)
class Noise:
    """RMS reading noise σ [in] (white noise and quantisation together) and the ADC step q [in] if any."""

    sigma: float
    adc_step: float | None

    @property
    def floor(self) -> float:
        """RMS of the reading error a perfect model would still see [in]: max(σ, q/√12)."""
        return max(self.sigma, (self.adc_step or 0.0) / np.sqrt(12.0))


def reading_noise(y: Array) -> float:
    """RMS [in] of the noise on the readings ``y`` (see module docstring)."""
    res = y - quintic_smooth(y)
    sq = np.sort(res**2)[: max(1, int(TRIM * res.size))]
    centre = float(SMOOTH[NOISE_WINDOW // 2])
    return float(np.sqrt(sq.mean() / TRIMMED_GAUSS / (1.0 - centre)))


def adc_step(y: Array) -> float | None:
    """The lattice step q [in] of quantised readings, or None if the readings are not on a lattice."""
    u = np.unique(np.round(y, 9))
    if u.size < 3 or u.size > 0.8 * y.size:
        return None
    gaps = np.diff(u)
    q = float(np.min(gaps[gaps > 1e-9])) if np.any(gaps > 1e-9) else 0.0
    if q <= 0:
        return None
    ratio = gaps / q
    whole = np.abs(ratio - np.round(ratio)) < 0.02
    return q if whole.mean() >= LATTICE_SHARE else None


def estimate(runs: Sequence[GapRun]) -> Noise:
    """The noise floor of the dataset (median over runs, the instability run excluded if others exist)."""
    quiet = [r for r in runs if r.kind != "instability"] or list(runs)
    sigma = float(np.median([reading_noise(r.y) for r in quiet]))
    steps = [s for s in (adc_step(r.y) for r in runs) if s is not None]
    q = float(np.median(steps)) if 2 * len(steps) >= len(runs) else None
    return Noise(sigma, q)
