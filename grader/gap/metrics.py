"""Fit measures and the quantities students read off a plot.

NRMSE = ‖y − ŷ‖ / ‖y − mean(y)‖ (``fit_percent`` = 100·(1 − NRMSE), MATLAB ``compare``).
Read-offs, each for the measured run and for a simulation of it: steady-state error
[in] (step: command minus the mean of the last 10 %; ramp: mean of r − y over the
last 20 %), overshoot [%] of the smoothed response over its final value, and the
oscillation frequency [Hz] (FFT peak of the detrended response after the command).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from grader.gap.lm import sumsq
from grader.gap.runs import GapRun
from grader.gap.segments import smooth

Array = NDArray[np.float64]


def nrmse(y: Array, y_hat: Array) -> float:
    """‖y − ŷ‖ / ‖y − mean(y)‖."""
    den = math.sqrt(sumsq(y - np.mean(y)))
    return math.sqrt(sumsq(y - y_hat)) / den if den > 0 else float("inf")


def fit_percent(y: Array, y_hat: Array) -> float:
    """MATLAB ``compare`` fit: 100·(1 − NRMSE)."""
    return 100.0 * (1.0 - nrmse(y, y_hat))


def steady_state_error(run: GapRun, y: Array) -> float:
    """Command minus response at the end of the run [in]."""
    if run.kind == "ramp":
        tail = max(1, run.n // 5)
        return float(np.mean(run.r[-tail:] - y[-tail:]))
    tail = max(1, run.n // 10)
    return float(run.r[-1] - np.mean(y[-tail:]))


def overshoot(run: GapRun, y: Array) -> float:
    """Peak overshoot of a step response over its final value [%] (0 if none)."""
    T = float(run.t[1] - run.t[0])
    ys = smooth(y, max(1, round(0.005 / T)))
    k0 = int(np.searchsorted(run.t, run.start))
    y0 = float(np.mean(y[:k0])) if k0 > 0 else float(y[0])
    yf = float(np.mean(y[-max(1, run.n // 10):]))
    step = yf - y0
    if step == 0:
        return 0.0
    peak = np.max((ys[k0:] - y0) / step) if k0 < run.n else 1.0
    return float(max(0.0, 100.0 * (peak - 1.0)))


def oscillation_frequency(run: GapRun, y: Array) -> float:
    """Dominant frequency [Hz] of the response after the command starts (drift and < 2 Hz ignored)."""
    k0 = int(np.searchsorted(run.t, run.start))
    x = y[k0:] - np.polyval(np.polyfit(run.t[k0:], y[k0:], 1), run.t[k0:])
    dt = float(run.t[1] - run.t[0])
    n = 1 << int(np.ceil(np.log2(16 * x.size)))
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size), n))
    freqs = np.fft.rfftfreq(n, dt)
    spec[freqs < 2.0] = 0.0
    return float(freqs[int(np.argmax(spec))])
