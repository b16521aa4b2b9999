"""One row per controller sample: a run's time stamps read onto the sample grid every ``sample_time``.

The dataset format (docs/reference/dataset-format.md) asks for one row per sample. :func:`load
<grader.datasets.load.load>` checks every run (:func:`check_rows`: a missing or repeated sample, or a sample_time
the rows do not have, is an error naming the row), so keys, grading and the diagnosis see the same data; the
diagnosis then reads the stamps onto the grid (:func:`sample_times`, stamps rounded for printing included).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from grader.errors import DatasetError

if TYPE_CHECKING:
    from grader.datasets.load import Run

Array = NDArray[np.float64]


def printed_resolution(t: Array) -> float:
    """The resolution [s, or the column's internal unit] the values were printed with: the median over rows of the
    largest power of ten from 1 down to 1e-9 of which a value is a multiple (a logger writing ``%.3f`` rounds a
    1.44 ms grid to whole milliseconds; a stamp that happens to end in zeros, as 1.000, shows a coarser one than
    the file's)."""
    res = np.zeros(t.size)
    for d in range(9, -1, -1):
        q = 10.0**-d
        res[np.abs(t / q - np.round(t / q)) < 1e-6] = q
    return float(np.median(res))


def _off_grid(run: Run, T: float, i: int) -> DatasetError:
    """The error naming row ``i`` (0-based, i ≥ 1) of a run whose rows are not one per controller sample every T."""
    t = run.t
    return DatasetError(
        f"run {run.name} ({run.spec.file}): rows are {(t[-1] - t[0]) / (t.size - 1) * 1e3:.4g} ms apart on average, "
        f"not evenly at the manifest's sample_time of {T * 1e3:g} ms (row {run.line(i)} is {(t[i] - t[i - 1]) * 1e3:.4g} "
        "ms after the one before); the data need one row per controller sample")


def check_rows(run: Run, T: float) -> None:
    """The check :func:`load <grader.datasets.load.load>` makes of every run: rows every ``T`` [s] on average
    (within 1 %: else the manifest's sample_time is not the data's), and no two rows less than half a sample or more
    than one and a half apart beyond the stamps' printed resolution (a repeated or a missing sample). Looser than
    :func:`sample_times`, which the diagnosis needs: a late stamp (a logger's jitter) still loads for a key."""
    t = run.t
    if t.size < 2:
        return
    dt, res = np.diff(t), printed_resolution(t)
    jumps = np.flatnonzero((dt > 1.5 * T + res) | (dt < 0.5 * T - res))
    if jumps.size:
        raise _off_grid(run, T, int(jumps[0]) + 1)
    if abs((t[-1] - t[0]) / (t.size - 1) - T) > 0.01 * T:
        raise _off_grid(run, T, int(np.argmax(np.abs(dt - T))) + 1)


def sample_times(run: Run, T: float) -> Array:
    """The run's time stamps [s] as controller samples every ``T``: as recorded where each row lies within 5 % of
    T of its sample; else the grid t₀ + k·T (t₀ centred in the offsets every row allows), where one grid takes
    every row within half the stamps' printed resolution plus 5 % of T (never half a sample). Raises
    :class:`DatasetError` otherwise, naming the first row no grid takes with the rows before it (a missing or
    repeated sample, or stamps too far off the grid for the diagnosis to put each on its sample)."""
    t, dt = run.t, np.diff(run.t)
    if abs(float(np.median(dt)) - T) <= 0.01 * T and np.max(np.abs(dt - T)) <= 0.05 * T:
        return t
    k = np.arange(t.size)
    off, tol = t - k * T, min(0.05 * T + 0.5 * printed_resolution(t), 0.499 * T)
    lo, hi = np.maximum.accumulate(off - tol), np.minimum.accumulate(off + tol)  # the offsets rows 0..k allow
    broken = np.flatnonzero(lo > hi)
    if broken.size == 0:
        return 0.5 * (lo[-1] + hi[-1]) + k * T
    raise _off_grid(run, T, int(broken[0]))
