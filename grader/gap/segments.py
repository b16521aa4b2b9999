"""Segments of a run, located on the *measured* response, and their share of the gap.

Step runs (normalised response n = (y − y₀)/(y_f − y₀), y_f the mean of the last 10 %):

* ``rise``: from the start of the run until n first reaches 0.9;
* ``overshoot``: from there until n falls back to 1 after the first peak above the
  band (empty when the response does not overshoot);
* ``settling``: until n last leaves the settling band (2 % of the step, widened to
  3σ of the noise);
* ``steady_state``: the rest.

Ramp runs are one ``tracking`` segment; the instability run one ``oscillation`` segment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from grader.gap.runs import GapRun

Array = NDArray[np.float64]
BAND = 0.02
SMOOTH_S = 0.005  # moving-average window for locating the segments [s]


@dataclass(frozen=True)
class Segment:
    """Samples [i0, i1) of a run."""

    name: str
    i0: int
    i1: int


def smooth(y: Array, n: int) -> Array:
    if n <= 1:
        return y
    k = np.ones(n) / n
    pad = np.concatenate([np.full(n // 2, y[0]), y, np.full(n - 1 - n // 2, y[-1])])
    return np.convolve(pad, k, mode="valid")


def _first(mask: Array, start: int = 0) -> int | None:
    hit = np.flatnonzero(mask[start:])
    return int(hit[0]) + start if hit.size else None


def step_segments(run: GapRun, sigma: float) -> list[Segment]:
    """rise, overshoot, settling, steady_state boundaries of a step run (see module docstring)."""
    T = float(run.t[1] - run.t[0])
    ys = smooth(run.y, max(1, round(SMOOTH_S / T)))
    k0 = int(np.searchsorted(run.t, run.start))
    y0 = float(np.mean(run.y[:k0])) if k0 > 0 else float(run.y[0])
    tail = max(1, run.n // 10)
    yf = float(np.mean(run.y[-tail:]))
    step = yf - y0
    if abs(step) < 3 * sigma or abs(step) == 0:
        return [Segment("rise", 0, 0), Segment("overshoot", 0, 0), Segment("settling", 0, 0),
                Segment("steady_state", 0, run.n)]
    n = (ys - y0) / step
    i90 = _first(n >= 0.9, k0)
    i90 = run.n if i90 is None else i90
    band = max(BAND, 3 * sigma / abs(step))
    i_back = i90
    above = _first(n > 1 + band, i90)
    if above is not None:
        back = _first(n <= 1.0, above)
        i_back = run.n if back is None else back
    outside = np.flatnonzero(np.abs(n[i_back:] - 1.0) > band)
    i_set = i_back + (int(outside[-1]) + 1 if outside.size else 0)
    return [Segment("rise", 0, i90), Segment("overshoot", i90, i_back), Segment("settling", i_back, i_set),
            Segment("steady_state", i_set, run.n)]


def segments_of(run: GapRun, sigma: float) -> list[Segment]:
    """The run's segments by kind."""
    if run.kind == "step":
        return step_segments(run, sigma)
    return [Segment("tracking" if run.kind == "ramp" else "oscillation", 0, run.n)]


def shares(residual: Array, segments: list[Segment]) -> list[float]:
    """Each segment's share of the run's squared residual (zeros if the residual is zero or not finite)."""
    sq = residual**2
    total = float(sq.sum())
    if not total > 0 or not np.isfinite(total):
        return [0.0 for _ in segments]
    return [float(sq[s.i0:s.i1].sum()) / total for s in segments]
