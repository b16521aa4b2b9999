"""Frequency of the oscillation in the instability run, estimated robustly.

The run's position is detrended, the dominant frequency found with a windowed,
zero-padded FFT, and then refined by least squares on
``y = c0 + c1·t + e^{σ(t−tm)}·(a·cos ωt + b·sin ωt)`` over the stretch where the
oscillation grows freely (before the DAC limit or saturation flattens its envelope).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy.optimize import least_squares

from grader.errors import IdentificationError
from grader.identify.estimate import Estimate


def _free_window(t: NDArray[np.float64], x: NDArray[np.float64], f0: float) -> NDArray[np.bool_]:
    """From a quarter second after the start until the envelope first reaches 90 % of its peak.
    The envelope comes from a band-pass round ``f0`` [Hz], its upper edge kept below the Nyquist
    frequency (a loop sampled slowly can oscillate at a few samples per cycle)."""
    fs = 1.0 / float(np.median(np.diff(t)))
    high = min(1.5 * f0, 0.45 * fs)
    b, a = signal.butter(2, [min(0.5 * f0, 0.5 * high), high], btype="band", fs=fs)
    env = np.abs(signal.hilbert(signal.filtfilt(b, a, x)))
    start = t[0] + 0.25 * (t[-1] - t[0]) if t[-1] - t[0] < 1.0 else t[0] + 0.25
    stop_idx = int(np.argmax(env >= 0.9 * env.max()))
    stop = max(t[stop_idx], start + 8.0 / f0)
    return (t >= start) & (t <= stop)


def _fft_peak(t: NDArray[np.float64], x: NDArray[np.float64]) -> float:
    dt = float(np.median(np.diff(t)))
    n = 1 << int(np.ceil(np.log2(16 * x.size)))
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(x.size), n))
    freqs = np.fft.rfftfreq(n, dt)
    spec[freqs < 2.0] = 0.0  # ignore drift and the step itself
    return float(freqs[int(np.argmax(spec))])


def _ar1_inflation(resid: NDArray[np.float64]) -> float:
    """Standard-error inflation for residuals correlated from sample to sample (AR(1)):
    sqrt((1 + ρ)/(1 − ρ)) with ρ the lag-1 autocorrelation (1 for white residuals)."""
    rho = float(np.corrcoef(resid[:-1], resid[1:])[0, 1]) if resid.size > 3 else 0.0
    rho = min(max(rho, 0.0), 0.99) if np.isfinite(rho) else 0.0
    return float(np.sqrt((1 + rho) / (1 - rho)))


def _harmonic_factor(sigma: float, dt: NDArray[np.float64]) -> float:
    """Harmonic mean of exp(σ·dt) over the window (1 for a steady oscillation)."""
    return float(1.0 / np.mean(np.exp(-np.clip(sigma * dt, -50, 50))))


class OscillationFit:
    """Learned: ``omega_`` [rad/s] and ``sigma_`` [1/s] (growth rate) as Estimates,
    ``amplitude_`` [in] of the oscillation, the harmonic mean over ``window_`` (t0, t1) [s], the fit's
    window (an amplitude-dependent damping such as Coulomb friction's acts on the fitted growth rate
    through 1/amplitude, averaged over the window)."""

    def fit(self, t: ArrayLike, y: ArrayLike, *, start: float = 0.0) -> OscillationFit:
        t, y = np.asarray(t, float), np.asarray(y, float)
        sel = t >= start
        t, y = t[sel], y[sel]
        if t.size < 50:
            raise IdentificationError("instability run: fewer than 50 samples after the command starts")
        x = signal.detrend(y)
        f0 = _fft_peak(t, x)
        if f0 <= 0 or not np.isfinite(f0):
            raise IdentificationError("instability run: no oscillation found")
        win = _free_window(t, x, f0)
        tw, yw = t[win], y[win]
        tm = float(tw.mean())
        w0 = 2 * np.pi * f0

        def model(p: NDArray[np.float64]) -> NDArray[np.float64]:
            c0, c1, sig, w, a, b = p
            e = np.exp(np.clip(sig * (tw - tm), -50, 50))
            return c0 + c1 * (tw - tm) + e * (a * np.cos(w * (tw - tm)) + b * np.sin(w * (tw - tm)))

        amp = float(np.std(yw - np.polyval(np.polyfit(tw, yw, 1), tw))) * np.sqrt(2)
        best = None
        for phase in (0.0, np.pi / 2, np.pi, 3 * np.pi / 2):
            p0 = [float(yw.mean()), 0.0, 0.0, w0, amp * np.cos(phase), amp * np.sin(phase)]
            res = least_squares(lambda p: model(p) - yw, p0, method="lm")
            if best is None or res.cost < best.cost:
                best = res
        assert best is not None
        dof = tw.size - 6
        cov = float(best.fun @ best.fun / dof) * np.linalg.pinv(best.jac.T @ best.jac)
        se = np.sqrt(np.diag(cov)) * _ar1_inflation(best.fun)
        if abs(best.x[3] - w0) > 0.25 * w0:
            raise IdentificationError("instability run: the oscillation is not a clean sinusoid (fit did not converge)")
        note = {"window_start [s]": float(tw[0]), "window_end [s]": float(tw[-1]), "fft_peak [Hz]": f0}
        self.omega_ = Estimate(abs(float(best.x[3])), "rad/s", float(se[3]), "FFT peak refined by a growing-sinusoid fit", note, dof)
        self.sigma_ = Estimate(float(best.x[2]), "1/s", float(se[2]), "growth rate of the same fit", note, dof)
        self.window_ = (float(tw[0]), float(tw[-1]))
        self.amplitude_ = float(np.hypot(best.x[4], best.x[5])) * _harmonic_factor(float(best.x[2]), tw - tm)
        return self
