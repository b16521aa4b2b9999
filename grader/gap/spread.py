"""How much a fitted model's own runs vary with the reading noise: the floor a second effect must beat.

The rig's controller acts on noisy readings, and some effects turn that noise into motion: a
backlash (valve hysteresis) or a deadband lets the noise walk the valve back and forth inside its
dead zone, stick-slip friction lets it decide when the mass breaks away. The same model then runs
differently under another draw of the noise, and no model can follow the rig's own draw closer than
that (the fitted model reads an estimate of it, :mod:`grader.gap.runs`). :func:`spread` simulates the
fitted model under :data:`DRAWS` further draws of noise like the estimate (white noise of the
readings' σ, high-passed by the same quintic smoothing, fixed seeds) and returns, per run, the mean
square of the normalised difference to the model's own run (:mod:`grader.gap.objective`): what the
reading noise alone adds to a correct model's NRMSE². A linear model's is next to nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from grader.gap.backend import Backend, Point
from grader.gap.lm import sumsq
from grader.gap.objective import RunObjective
from grader.gap.runs import NOISE_WINDOW, quintic_smooth

Array = NDArray[np.float64]
DRAWS = 3
SEED = 20261124


def _like_estimate(n: int, sigma: float, rng: np.random.Generator) -> Array:
    w = rng.normal(0.0, sigma, n)
    return w - quintic_smooth(w) if n > NOISE_WINDOW else w


def spread(objectives: Sequence[RunObjective], point: Point, sigma: float, *, draws: int = DRAWS) -> Array:
    """Per run, the mean over ``draws`` noise draws of the squared norm of the normalised difference between
    ``point``'s run under that draw and under the run's estimated noise (see module docstring)."""
    rng = np.random.default_rng(SEED)
    runs = [o.run for o in objectives]
    variants = [runs] + [[replace(r, noise=_like_estimate(r.n, sigma, rng)) if np.any(r.noise) else r for r in runs]
                         for _ in range(draws)]
    flat = [replace(r, name=f"{r.name}#{k}") for k, vs in enumerate(variants) for r in vs]
    xs = Backend(flat).all_runs([point])[0]
    n = len(runs)
    own = [o.residual(x) for o, x in zip(objectives, xs[:n])]
    out = np.zeros(n)
    for k in range(1, draws + 1):
        for i, o in enumerate(objectives):
            d = o.residual(xs[k * n + i]) - own[i]
            out[i] += sumsq(d) / draws
    return out
