"""Frequency and growth rate of the oscillation in the instability run, estimated robustly.

The run's position is detrended, the dominant frequency found with a windowed,
zero-padded FFT, and then refined by least squares over the stretch where the
oscillation grows freely (before valve or DAC saturation flattens its envelope) on

    y = c0 + c1·τ + a(τ)/a0 · (a·cos ωτ + b·sin ωτ),   da/dτ = σ·a − c,

the envelope of a loop whose linear growth rate is σ and whose Coulomb friction takes a
constant ``decrement`` c [in/s] off the amplitude's growth (describing function: friction's
equivalent damping 4·Fc/(π·a·ω) slows the growth by a rate ∝ 1/a). With c from the friction
test, σ is the linear loop's growth rate at every amplitude the window spans.

The window also ends where friction stops the oscillation (its envelope fades): a loop just
past the critical gain may grow at large amplitude yet decay at small. A run without
:data:`MIN_CYCLES` cycles above an ADC count (a friction or quantisation limit cycle, or no
oscillation) is flagged: ``usable_`` is False, ``why_not_`` says why and nothing else is learned.

:func:`sustained` is the students' test of an instability run, for a simulated one: whether its oscillation
lasts (the benchmark's generator raises the gain until it does; the diagnosis reads the augmented model's
critical gain with it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy.optimize import least_squares

from grader.errors import IdentificationError
from grader.identify.estimate import Estimate

Array = NDArray[np.float64]
#: an oscillation counts while its amplitude is at least this many recording steps (ADC counts) and
#: this share of the step command (below: a friction or quantisation limit cycle)
MIN_COUNTS, MIN_STEP_SHARE = 1.0, 0.005
#: the free-growth window ends where the envelope reaches this share of the saturation amplitude,
#: or falls to this share of its starting value; it must span :data:`MIN_CYCLES` cycles
SATURATION_SHARE, FADED, MIN_CYCLES = 0.8, 0.25, 8
#: fewest readings in the window (a run that ends where the oscillation starts left one, and the six-parameter
#: fit of a growing sinusoid failed on it, stopping the diagnosis of an 8-bit ADC's dataset)
MIN_WINDOW = 20
#: An oscillation lasts where its peak-to-peak over a run's last LATE s is at least LASTS of that over the EARLY
#: window after its command, and at least SPANS of the command's step.
EARLY, LATE, LASTS, SPANS = (0.1, 0.3), 0.2, 0.9, 0.2


def sustained(y: Array, t: Array, start: float, step: float) -> NDArray[np.bool_]:
    """For each run of positions ``y`` [in] (rows, at times ``t`` [s]; the command steps by ``step`` [in] at
    ``start`` [s]), whether its oscillation at the end has not decayed and spans at least :data:`SPANS` of the step
    peak to peak (a loop that jumps straight into a saturated limit cycle is unstable too). A friction or
    quantisation limit cycle of a few ADC counts, or noise, is not an unstable loop: a student raises the gain
    further. False for every run where a window holds no sample."""
    early_window = (t >= start + EARLY[0]) & (t < start + EARLY[1])
    late_window = t >= t[-1] - LATE
    if not early_window.any() or not late_window.any():
        return np.zeros(len(y), dtype=bool)
    early, late = np.ptp(y[:, early_window], axis=1), np.ptp(y[:, late_window], axis=1)
    return (late > LASTS * early) & (late > SPANS * step)


def _envelope(t: Array, x: Array, f0: float) -> Array:
    """Envelope of ``x`` band-passed round ``f0`` [Hz], the upper edge kept below the Nyquist
    frequency (a loop sampled slowly can oscillate at a few samples per cycle)."""
    fs = 1.0 / float(np.median(np.diff(t)))
    high = min(1.5 * f0, 0.45 * fs)
    b, a = signal.butter(2, [min(0.5 * f0, 0.5 * high), high], btype="band", fs=fs)
    return np.abs(signal.hilbert(signal.filtfilt(b, a, x)))


def _settled(t: Array, y: Array, env: Array, f0: float, a_sat: float) -> float:
    """When the step's transient is over [s]: two cycles after the position first crosses its
    median level, once the envelope is below the saturation amplitude ``a_sat`` [in]; at most a
    quarter second after the start (a quarter of the run if shorter than a second)."""
    latest = t[0] + 0.25 * (t[-1] - t[0]) if t[-1] - t[0] < 1.0 else t[0] + 0.25
    level = float(np.median(y))
    crossed = np.flatnonzero(np.sign(y - level) != np.sign(y[0] - level))
    calm = np.flatnonzero((t > (t[crossed[0]] if crossed.size else latest) + 2.0 / f0) & (env < SATURATION_SHARE * a_sat))
    return min(float(t[calm[0]]) if calm.size else latest, latest)


def _free_window(t: Array, y: Array, env: Array, f0: float, a_sat: float, floor: float) -> tuple[NDArray[np.bool_], bool]:
    """(window, usable): from :func:`_settled` until the envelope first reaches
    90 % of its peak or :data:`SATURATION_SHARE` of the saturation amplitude ``a_sat`` [in] (at least
    :data:`MIN_CYCLES` cycles), or fades below a quarter of its starting value or the
    ``floor`` [in] (an oscillation that friction stops: usable only after that many cycles)."""
    start = _settled(t, y, env, f0, a_sat)
    after = t > start
    env0 = float(env[np.argmax(after)])
    grown = np.flatnonzero(after & (env >= min(0.9 * env.max(), SATURATION_SHARE * a_sat)))
    faded = np.flatnonzero(after & (env < max(FADED * env0, floor)))
    t_fade = t[faded[0]] if faded.size else np.inf
    if t_fade < (t[grown[0]] if grown.size else np.inf):
        return (t >= start) & (t <= t_fade), (t_fade - start) * f0 >= MIN_CYCLES
    stop = max(t[grown[0]] if grown.size else t[-1], start + MIN_CYCLES / f0)
    return (t >= start) & (t <= min(stop, t_fade)), True


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
    ``usable_`` / ``why_not_`` (see the module docstring). ``a_sat`` [in] is the amplitude
    at which the valve or DAC saturates (the window ends before it)."""

    def __init__(self, a_sat: float = np.inf) -> None:
        self.a_sat = a_sat

    def fit(self, t: ArrayLike, y: ArrayLike, *, start: float = 0.0, decrement: float = 0.0,
            guess: OscillationFit | None = None) -> OscillationFit:
        """Fit the run; ``decrement`` [in/s] is Coulomb friction's take off the amplitude's growth;
        ``guess``, an earlier fit of the same run, seeds the least squares (else four phases are tried)."""
        t, y = np.asarray(t, float), np.asarray(y, float)
        sel = t >= start
        before = float(np.mean(y[~sel])) if np.any(~sel) else float(y[0])
        t, y = t[sel], y[sel]
        if t.size < 50:
            raise IdentificationError("instability run: fewer than 50 samples after the command starts")
        with np.errstate(over="ignore", invalid="ignore"):  # squares that overflow: no least squares can start
            too_large = not np.isfinite(y @ y)
        if too_large:
            raise IdentificationError("instability run: the readings are too large to fit an oscillation to")
        x = signal.detrend(y)
        f0 = _fft_peak(t, x)
        if f0 <= 0 or not np.isfinite(f0):
            raise IdentificationError("instability run: no oscillation found")
        env = _envelope(t, x, f0)
        floor = max(MIN_COUNTS * _quantum(y), MIN_STEP_SHARE * abs(float(np.median(y)) - before))
        win, self.usable_ = _free_window(t, y, env, f0, self.a_sat, floor)
        tw, yw = t[win], y[win]
        self.usable_ = self.usable_ and tw.size >= MIN_WINDOW  # a window cut short by the run's end
        cycles = (tw[-1] - tw[0]) * f0 if tw.size else 0.0
        self.why_not_ = None if self.usable_ else (
            f"the instability run shows {cycles:.0f} cycles of oscillation above {floor:.2g} in (an ADC count or "
            f"0.5 % of the step) before it dies out, fewer than {MIN_CYCLES}: no critical oscillation to read")
        if not self.usable_:
            return self
        tau = tw - float(tw.mean())
        best = self._least_squares(tau, yw, 2 * np.pi * f0, decrement, getattr(guess, "_p", None))
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
        self._p = best.x
        return self

    @staticmethod
    def _least_squares(tau: Array, yw: Array, w0: float, decrement: float,  # type: ignore[no-untyped-def]
                       guess: Array | None):
        def model(p: Array) -> Array:
            c0, c1, sig, w, a, b = p
            return c0 + c1 * tau + envelope_factor(sig, decrement, float(np.hypot(a, b)), tau) * (
                a * np.cos(w * tau) + b * np.sin(w * tau))

        amp = float(np.std(yw - np.polyval(np.polyfit(tau, yw, 1), tau))) * np.sqrt(2)
        best = None
        starts = [list(guess)] if guess is not None else [
            [float(yw.mean()), 0.0, 0.0, w0, amp * np.cos(ph), amp * np.sin(ph)] for ph in (0.0, np.pi / 2, np.pi, 1.5 * np.pi)]
        for p0 in starts:
            res = least_squares(lambda p: model(p) - yw, p0, method="lm", x_scale="jac")
            if best is None or res.cost < best.cost:
                best = res
        assert best is not None
        return best
