"""The augmented model's critical gain: the least P gain at which its instability run does not die out.

The linear model's critical gain is exact (:func:`grader.model.zloop.critical_gain`: the sampled loop's roots
reach the unit circle). A model with an unmodelled effect has none in closed form, so its instability run is
simulated at :data:`GRID` gains at once, log-spaced over [guess/:data:`SPAN`, guess·SPAN] around a guess (the
linear model's), and again over the grid step where it first lasts: the first gain whose oscillation is not
dying out (the RMS of the position's sample-to-sample change over the run's last third at least :data:`LASTS`
of that over its middle third; a limit cycle that a current limit or friction holds at one amplitude lasts,
and a decaying one does not) and spans at least :data:`SPANS` of the command's step peak to peak (an ADC's
limit cycle of a few counts is no instability, as for the students). The result is that first lasting gain:
within a fine grid step, (SPAN²)^(1/(GRID−1)²) or 0.8 %, of the boundary (and up to 0.3 % below it, where an
oscillation decays too slowly for LASTS to tell); None where no gain of the grid is the first to last.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from grader.gap.backend import Backend, Point
from grader.gap.runs import GapRun
from grader.model import zloop

Array = NDArray[np.float64]
GRID, SPAN = 24, 4.0
LASTS, SPANS = 0.95, 0.2


def lasts(x: Array, step: float) -> bool:
    """Whether the oscillation of positions ``x`` [in] on a command stepping by ``step`` [in] is not dying out
    (module docstring)."""
    v = np.diff(x)
    third = v.size // 3
    mid, late = v[third:2 * third], v[2 * third:]
    return bool(np.sqrt(np.mean(late**2)) >= LASTS * np.sqrt(np.mean(mid**2))
                and np.ptp(x[2 * third:]) >= SPANS * step)


def _first_lasting(point: Point, run: GapRun, gains: Array) -> int | None:
    runs = [replace(run, controller=replace(run.controller, Kp=float(k))) for k in gains]
    xs = Backend(runs).all_runs([point])[0]
    lasting = [k for k, x in enumerate(xs) if lasts(x, float(np.ptp(run.r)))]
    return lasting[0] if lasting else None


def critical_gain(point: Point, run: GapRun) -> float | None:
    """The model's critical gain [the run's Kp convention] on the instability ``run`` (module docstring); exact for
    a model without effects."""
    guess = zloop.critical_gain(point.params)
    if not point.effects.values:
        return guess if np.isfinite(guess) else None
    guess = guess if np.isfinite(guess) else run.controller.Kp
    coarse = guess * np.geomspace(1.0 / SPAN, SPAN, GRID)
    k = _first_lasting(point, run, coarse)
    if not k:  # none lasts, or the least gain tried already does: the boundary is not on the grid
        return None
    fine = np.geomspace(coarse[k - 1], coarse[k], GRID)[1:]
    j = _first_lasting(point, run, fine)
    return float(fine[j]) if j is not None else float(coarse[k])
