"""The fit objective: a model's positions x_k [in] against a run's readings y_k [in], as one residual vector.

Step and ramp runs are compared sample by sample: ``(x_k − y_k)/(scale·√n)``, whose sum of squares is
the run's NRMSE². So is the instability run over the step and the onset of its oscillation (the first
:data:`ONSET_CYCLES` periods after the command). After that, fifty cycles at the margin of stability
are a phase lottery: a model whose frequency is off by a per cent drifts out of phase, and a
sample-by-sample residual would then measure the phase, not the model, and trap the fit. There the
oscillation is compared without its phase, in windows of :data:`WINDOW_CYCLES` periods: its mean
level, its RMS amplitude and its frequency (the RMS of the first difference over the RMS, in radians
per sample), each of both signals after the same quintic smoothing. The frequency enters as its
relative error times the window's amplitude times :data:`FREQ_WEIGHT`, the amplitude's error times
:data:`AMP_WEIGHT`; each window's entries weigh as many samples as it holds. A run whose oscillation
a model does not reproduce therefore costs about what it costs sample by sample, without the lottery
and its trapped fits. The readings' amplitude and rate are corrected for the reading noise σ the
smoothing lets through (the model's positions carry none). A run's entries may all carry a
``weight`` below 1 (:func:`grader.gap.diagnose.analyse` down-weights runs the reading noise makes
wander, :mod:`grader.gap.spread`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import convolve1d

from grader.gap.metrics import oscillation_frequency
from grader.gap.runs import NOISE_WINDOW, SMOOTH, GapRun, truncated

Array = NDArray[np.float64]
ONSET_CYCLES = 4.0
WINDOW_CYCLES = 4.0
#: Weights of a window's amplitude and relative-frequency entries. The amplitude of an oscillation at the margin
#: of stability also follows the rig's own draw of the noise (a correct linear model misses it by several times
#: the noise floor), so it weighs less; a frequency error of 1 % costs what 3 % of the amplitude would.
AMP_WEIGHT, FREQ_WEIGHT = 0.3, 3.0
#: Bounds on the onset stretch [s] after the command (a run with no readable oscillation takes the upper one).
ONSET_BOUNDS = (0.05, 0.25)
MIN_WINDOW = 8  # samples


@dataclass(frozen=True)
class RunObjective:
    """How one run is compared (see module docstring): samples [0, k0) one by one, then windows of w samples."""

    run: GapRun
    k0: int
    w: int
    mean: Array  # per window, the readings' smoothed mean [in]
    amp: Array  # per window, their RMS about it [in]
    rate: Array  # per window, the RMS of their first difference [in per sample]
    weight: float = 1.0  # every entry's factor (below 1 for a run the reading noise makes wander)

    def cut(self, duration: float | None) -> RunObjective:
        """This objective on the run's first ``duration`` seconds after its command (None: whole)."""
        if duration is None:
            return self
        run = truncated(self.run, duration)
        if run.n == self.run.n:
            return self
        k0 = min(self.k0, run.n)
        m = max(0, (run.n - k0) // self.w) if self.mean.size else 0
        return RunObjective(run, k0, self.w, self.mean[:m], self.amp[:m], self.rate[:m], self.weight)

    @property
    def length(self) -> int:
        """Entries in the residual vector."""
        return self.k0 + 3 * self.mean.size

    def residual(self, x: Array) -> Array:
        """The normalised residual of positions ``x`` (same samples as the run)."""
        norm = self.run.scale * np.sqrt(self.run.n) / self.weight
        head = (x[:self.k0] - self.run.y[:self.k0]) / norm
        if self.mean.size == 0:
            return head
        mean, amp, rate = _features(x, self.k0, self.w)
        omega = self.rate / np.maximum(self.amp, 1e-12)  # radians per sample, per window
        seen = amp > 1e-3 * self.amp  # the model oscillates in that window: its frequency is defined
        freq = np.where(seen, rate / np.maximum(amp, 1e-12) / np.maximum(omega, 1e-12) - 1.0, 0.0) * FREQ_WEIGHT * self.amp
        weight = np.sqrt(self.w) / norm
        return np.concatenate([head, (mean - self.mean) * weight, (amp - self.amp) * (AMP_WEIGHT * weight), freq * weight])


def _features(x: Array, k0: int, w: int) -> tuple[Array, Array, Array]:
    """Per window of ``w`` samples from ``k0``: smoothed mean, RMS about it, RMS of the first difference."""
    m = (x.size - k0) // w
    if m <= 0:
        return np.empty(0), np.empty(0), np.empty(0)
    z = convolve1d(x, SMOOTH, mode="nearest")[k0:k0 + m * w].reshape(m, w)
    mean = z.mean(axis=1)
    dev = z - mean[:, None]
    return mean, np.sqrt(np.mean(dev**2, axis=1)), np.sqrt(np.mean(np.diff(z, axis=1) ** 2, axis=1))


def _noise_gains() -> tuple[float, float]:
    """Variance of smoothed white noise of unit σ, and of its first difference."""
    return float(np.sum(SMOOTH * SMOOTH)), float(np.sum(np.diff(np.concatenate([[0.0], SMOOTH, [0.0]])) ** 2))


def objective(run: GapRun, sigma: float = 0.0) -> RunObjective:
    """The run's objective (see module docstring); ``sigma`` [in] is the reading noise."""
    if run.kind != "instability":
        return RunObjective(run, run.n, 1, np.empty(0), np.empty(0), np.empty(0))
    T = float(run.t[1] - run.t[0])
    f = oscillation_frequency(run, run.y) if run.n > NOISE_WINDOW else 0.0
    period = 1.0 / f if f > 0 else ONSET_BOUNDS[1] / ONSET_CYCLES
    onset = float(np.clip(ONSET_CYCLES * period, *ONSET_BOUNDS))
    k0 = min(run.n, int(np.searchsorted(run.t, run.start + onset)))
    w = max(MIN_WINDOW, int(round(WINDOW_CYCLES * period / T)))
    if run.n - k0 < w or run.n <= NOISE_WINDOW:
        return RunObjective(run, run.n, 1, np.empty(0), np.empty(0), np.empty(0))
    mean, amp, rate = _features(run.y, k0, w)
    g_amp, g_rate = _noise_gains()
    amp = np.sqrt(np.maximum(amp**2 - g_amp * sigma**2, 0.0))
    rate = np.sqrt(np.maximum(rate**2 - g_rate * sigma**2, 0.0))
    return RunObjective(run, k0, w, mean, amp, rate)
