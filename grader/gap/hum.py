"""Mains pickup on the position readings: the lines at 50 or 60 Hz and their harmonics that the runs' rests show.

A pot's wiring picks up the mains, and the hum sits on the readings the rig's controller acts on. The replayed runs
(:mod:`grader.gap.replay`) are cleared of the lines found here, and of no others: a run's own motion can have a
component at a mains frequency (a limit cycle at 20 Hz has its 3rd and 5th harmonics at 60 and 100 Hz), and clearing
a line that is no hum would throw away what tells two effects apart. On the independent simulator's 113 datasets,
the rests show the 60 Hz pickup of 18 of the 24 rigs that have it (the others sample every 2.5 ms or slower: too
few readings at rest) and a line on 2 of the 89 that have none; on benchmark run A's 310 rigs, which have none, no
line.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from grader.gap.runs import GapRun

Array = NDArray[np.float64]
#: Mains frequencies [Hz] looked for: 50 and 60 Hz and their second and third harmonics.
MAINS = (50.0, 60.0, 100.0, 120.0, 150.0, 180.0)
#: Significance of the pooled F test at which a line counts as found: 6 lines are tested on every dataset, so noise
#: alone shows one about once in 17,000 datasets, while pickup as large as the reading noise scores below 1e-10.
ALPHA = 1e-5
#: Fewest readings at rest a run needs to take part in the test.
MIN_REST = 8


def basis(t: Array, freqs: Sequence[float]) -> Array:
    """Orthonormal columns (samples × k) spanning a constant, a straight line in the times ``t`` [s], and a sine and a
    cosine at each of ``freqs`` [Hz], as sampled (a line that aliases onto another's, onto 0 or onto the Nyquist
    frequency adds what it can, or nothing). Modified Gram–Schmidt with numpy's own reductions, no BLAS, so every
    CPU gets the same bits."""
    tc = t - np.mean(t)
    cols = [np.ones_like(t), tc]
    for f in freqs:
        cols += [np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)]
    out: list[Array] = []
    unit = float(np.sqrt(t.size))  # the norm of a column of ones: a sampled sine is of its order unless it vanishes
    for k, c in enumerate(cols):
        size = max(float(np.sqrt(np.sum(c * c))), 0.0 if k == 1 else unit)  # the line's norm is its span's
        for q in out:
            c = c - q * np.sum(q * c)
        norm = float(np.sqrt(np.sum(c * c)))
        if norm > 1e-6 * size:
            out.append(c / norm)
    return np.stack(out, axis=1)


def lines(runs: Sequence[GapRun]) -> tuple[float, ...]:
    """The mains frequencies [Hz] (:data:`MAINS`) whose sine and cosine explain more of the runs' readings at rest
    (before each command, less a straight line) than the reading noise would: an F test pooled over the runs with
    :data:`MIN_REST` or more readings at rest, at :data:`ALPHA`. The instability run takes no part: a rig that rests
    at its gain before the command already rings near the critical frequency (run A's 0001, which has no pickup,
    showed a 60 Hz line there at p = 3e-13, and in no other run)."""
    found = []
    for f in MAINS:
        line = noise = 0.0
        k = dof = 0
        for run in runs:
            rest = run.t < run.start
            if run.kind == "instability":
                continue
            if int(rest.sum()) < MIN_REST:
                continue
            q = basis(run.t[rest], (f,))
            if q.shape[1] < 4:  # the line aliases onto 0 or the Nyquist frequency of so few readings
                continue
            y = run.y[rest]
            c = np.sum(q * y[:, None], axis=0)
            line += float(c[2] ** 2 + c[3] ** 2)
            noise += float(np.sum((y - np.sum(q * c, axis=1)) ** 2))
            k, dof = k + 2, dof + y.size - 4
        if k and dof > 0 and noise > 0 and stats.f.sf((line / k) / (noise / dof), k, dof) < ALPHA:
            found.append(f)
    return tuple(found)
