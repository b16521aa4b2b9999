"""Frequency and growth rate of the oscillation in the instability run, estimated robustly.

The run's position is detrended, the dominant frequency found with a windowed,
zero-padded FFT, and then refined by least squares over the stretch where the
oscillation grows freely (before valve or DAC saturation flattens its envelope) on

    y = c0 + c1·τ + a(τ)/a0 · (a·cos ωτ + b·sin ωτ),   da/dτ = σ·a − c,

the envelope of a loop whose linear growth rate is σ and whose Coulomb friction takes a
constant ``decrement`` c [in/s] off the amplitude's growth (describing function: friction's
equivalent damping 4·Fc/(π·a·ω) slows the growth by a rate ∝ 1/a). With c from the friction
test, σ is the linear loop's growth rate at every amplitude the window spans.

A run whose oscillation dies out, or stays within a few ADC counts (a friction or
quantisation limit cycle, not the loop's critical oscillation), is flagged: ``sustained_``
is False and ``why_not_`` says why.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy.optimize import least_squares

from grader.errors import IdentificationError
from grader.identify.estimate import Estimate

Array = NDArray[np.float64]
#: a sustained oscillation ends at least this many ADC counts and this share of the step in amplitude
MIN_COUNTS, MIN_STEP_SHARE = 3.0, 0.01
#: the free-growth window ends where the envelope reaches this share of the saturation amplitude
SATURATION_SHARE = 0.8


def _envelope(t: Array, x: Array, f0: float) -> Array:
    """Envelope of ``x`` band-passed round ``f0`` [Hz], the upper edge kept below the Nyquist
    frequency (a loop sampled slowly can oscillate at a few samples per cycle)."""
    fs = 1.0 / float(np.median(np.diff(t)))
    high = min(1.5 * f0, 0.45 * fs)
    b, a = signal.butter(2, [min(0.5 * f0, 0.5 * high), high], btype="band", fs=fs)
    return np.abs(signal.hilbert(signal.filtfilt(b, a, x)))


def _free_window(t: Array, env: Array, f0: float, a_sat: float) -> NDArray[np.bool_]:
    """From a quarter second after the start until the envelope first reaches 90 % of its peak
    or :data:`SATURATION_SHARE` of the saturation amplitude ``a_sat`` [in] (at least 8 cycles)."""
    start = t[0] + 0.25 * (t[-1] - t[0]) if t[-1] - t[0] < 1.0 else t[0] + 0.25
    past = np.flatnonzero((env >= min(0.9 * env.max(), SATURATION_SHARE * a_sat)) & (t > start))
    stop = max(t[past[0]] if past.size else t[-1], start + 8.0 / f0)
    return (t >= start) & (t <= stop)


def _fft_peak(t: Array, x: Array) -> float:
    dt = float(np.median(np.diff(t)))
    n = 1 << int(np.ceil(np.log2(16 * x.size)))
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(x.size), n))
    freqs = np.fft.rfftfreq(n, dt)
    spec[freqs < 2.0] = 0.0  # ignore drift and the step itself
    return float(freqs[int(np.argmax(spec))])


def _ar1_inflation(resid: Array) -> float:
    """Standard-error inflation for residuals correlated from sample to sample (AR(1)):
    sqrt((1 + ρ)/(1 − ρ)) with ρ the lag-1 autocorrelation (1 for white residuals)."""
    rho = float(np.corrcoef(resid[:-1], resid[1:])[0, 1]) if resid.size > 3 else 0.0
    rho = min(max(rho, 0.0), 0.99) if np.isfinite(rho) else 0.0
    return float(np.sqrt((1 + rho) / (1 - rho)))


def _quantum(y: Array) -> float:
    """The position's recording step [in]: the smallest difference between recorded values."""
    steps = np.diff(np.unique(y))
    return float(steps.min()) if steps.size else 0.0


def envelope_factor(sigma: float, decrement: float, a0: float, tau: Array) -> Array:
    """a(τ)/a0 for da/dτ = σ·a − c with a(0) = a0 [in] (never below 0: friction stops the motion)."""
    e = np.exp(np.clip(sigma * tau, -50, 50))
    ramp = np.expm1(np.clip(sigma * tau, -50, 50)) / sigma if abs(sigma) > 1e-9 else tau
    return np.maximum(e - decrement / max(a0, 1e-12) * ramp, 0.0)


class OscillationFit:
    """Learned: ``omega_`` [rad/s] and ``sigma_`` [1/s] (the linear growth rate) as Estimates,
    ``amplitude_`` [in] at the middle of ``window_`` (t0, t1) [s], the fit's window, and
    ``sustained_`` / ``why_not_`` (see the module docstring). ``a_sat`` [in] is the amplitude
    at which the valve or DAC saturates (the window ends before it)."""

    def __init__(self, a_sat: float = np.inf) -> None:
        self.a_sat = a_sat

    def fit(self, t: ArrayLike, y: ArrayLike, *, start: float = 0.0, decrement: float = 0.0) -> OscillationFit:
        """Fit the run; ``decrement`` [in/s] is Coulomb friction's take off the amplitude's growth."""
        t, y = np.asarray(t, float), np.asarray(y, float)
        sel = t >= start
        t, y = t[sel], y[sel]
        if t.size < 50:
            raise IdentificationError("instability run: fewer than 50 samples after the command starts")
        x = signal.detrend(y)
        f0 = _fft_peak(t, x)
        if f0 <= 0 or not np.isfinite(f0):
            raise IdentificationError("instability run: no oscillation found")
        env = _envelope(t, x, f0)
        self._judge(t, y, env)
        win = _free_window(t, env, f0, self.a_sat)
        tw, yw = t[win], y[win]
        tau = tw - float(tw.mean())
        best = self._least_squares(tau, yw, 2 * np.pi * f0, decrement)
        dof = tw.size - 6
        cov = float(best.fun @ best.fun / dof) * np.linalg.pinv(best.jac.T @ best.jac)
        se = np.sqrt(np.diag(cov)) * _ar1_inflation(best.fun)
        if abs(best.x[3] - 2 * np.pi * f0) > 0.25 * 2 * np.pi * f0:
            raise IdentificationError("instability run: the oscillation is not a clean sinusoid (fit did not converge)")
        note = {"window_start [s]": float(tw[0]), "window_end [s]": float(tw[-1]), "fft_peak [Hz]": f0,
                "friction decrement [in/s]": decrement}
        self.omega_ = Estimate(abs(float(best.x[3])), "rad/s", float(se[3]), "FFT peak refined by a growing-sinusoid fit", note, dof)
        self.sigma_ = Estimate(float(best.x[2]), "1/s", float(se[2]),
                               "linear growth rate of the same fit (friction's decrement taken out)", note, dof)
        self.window_ = (float(tw[0]), float(tw[-1]))
        self.amplitude_ = float(np.hypot(best.x[4], best.x[5]))
        return self

    @staticmethod
    def _least_squares(tau: Array, yw: Array, w0: float, decrement: float):  # type: ignore[no-untyped-def]
        def model(p: Array) -> Array:
            c0, c1, sig, w, a, b = p
            return c0 + c1 * tau + envelope_factor(sig, decrement, float(np.hypot(a, b)), tau) * (
                a * np.cos(w * tau) + b * np.sin(w * tau))

        amp = float(np.std(yw - np.polyval(np.polyfit(tau, yw, 1), tau))) * np.sqrt(2)
        best = None
        for phase in (0.0, np.pi / 2, np.pi, 3 * np.pi / 2):
            p0 = [float(yw.mean()), 0.0, 0.0, w0, amp * np.cos(phase), amp * np.sin(phase)]
            res = least_squares(lambda p: model(p) - yw, p0, method="lm")
            if best is None or res.cost < best.cost:
                best = res
        assert best is not None
        return best

    def _judge(self, t: Array, y: Array, env: Array) -> None:
        """Whether the oscillation is sustained: it does not die out after the step's transient and
        ends above a few ADC counts and 1 % of the step (else a friction or quantisation limit cycle)."""
        t0 = t[0] + min(0.25, 0.25 * (t[-1] - t[0]))
        early = float(np.median(env[(t >= t0) & (t < t0 + 0.1)])) if np.any((t >= t0) & (t < t0 + 0.1)) else float(env[0])
        late = float(np.median(env[t >= t[-1] - min(0.2, 0.2 * (t[-1] - t[0]))]))
        floor = max(MIN_COUNTS * _quantum(y), MIN_STEP_SHARE * float(np.ptp(y)))
        self.sustained_, self.why_not_ = True, None
        if late < floor:
            self.sustained_ = False
            self.why_not_ = (f"the instability run's oscillation ends at {late:.2g} in, within a few ADC counts or 1 % of "
                             f"the step: a friction or quantisation limit cycle, not the loop's critical oscillation")
        elif late < 0.5 * early:
            self.sustained_ = False
            self.why_not_ = (f"the instability run's oscillation dies out ({early:.2g} in falls to {late:.2g} in): "
                             f"the loop is stable at the run's gain")
