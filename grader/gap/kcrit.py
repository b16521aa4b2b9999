"""The augmented model's critical gain: the least P gain at which its instability run does not die out.

The linear model's critical gain is exact (:func:`grader.model.zloop.critical_gain`: the sampled loop's roots
reach the unit circle). A model with an unmodelled effect has none in closed form, so its instability run is
simulated at :data:`GRID` gains at once, log-spaced over [guess/:data:`SPAN`, guess·SPAN] around a guess (the
linear model's), and again over the grid step where it first lasts, by the students' test, the one the benchmark's
generator raises the gain with (:func:`grader.identify.oscillation.sustained`: the oscillation at the run's end
has not decayed and spans a fifth of the step; a limit cycle that a current limit or friction holds lasts, an
ADC's of a few counts does not). The result is that first lasting gain: within a fine grid step,
(SPAN²)^(1/(GRID−1)²) or 0.8 %, of the boundary (and a little below it, where an oscillation decays too slowly for
the test to tell in one run); None where no gain of the grid is the first to last.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from grader.gap.backend import Backend, Point
from grader.gap.runs import GapRun
from grader.identify.oscillation import sustained
from grader.model import zloop

Array = NDArray[np.float64]
GRID, SPAN = 24, 4.0


def _first_lasting(point: Point, run: GapRun, gains: Array) -> int | None:
    runs = [replace(run, controller=replace(run.controller, Kp=float(k))) for k in gains]
    xs = np.stack(Backend(runs).all_runs([point])[0])
    lasting = np.flatnonzero(sustained(xs, run.t, run.start, float(np.ptp(run.r))))
    return int(lasting[0]) if lasting.size else None


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
