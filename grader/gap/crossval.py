"""Leave-one-run-out cross-validation of fitted candidates.

For each run left out, every candidate is re-fitted on the other runs, starting from
its all-runs optimum θ* (whose residuals and Jacobian restricted to the training runs
are already known), by a few batched Levenberg–Marquardt rounds; it is then simulated
on the left-out run only, and the norm of its residual there (:mod:`grader.gap.objective`:
the NRMSE, with the instability run's oscillation compared without its phase) is the
held-out gap. The fold estimates θ_f also give jackknife standard errors of the parameters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from grader.gap.fit import BatchFitter, FitState
from grader.gap.lm import sumsq

Array = NDArray[np.float64]
FOLD_ROUNDS = 2
FLOOR = 1e-9


def typical(values: Array, weights: Array | None = None) -> float:
    """Weighted geometric mean: the typical per-run value. One run the other runs cannot predict
    (a fifty-cycle oscillation at the margin of stability, a phase lottery) moves it by its own share
    only, where it would swamp an arithmetic mean."""
    return float(np.exp(np.average(np.log(np.maximum(values, FLOOR)), weights=weights)))


@dataclass(frozen=True)
class CrossValidation:
    """Held-out NRMSE per run and fold parameter estimates ``thetas`` (folds × θ)."""

    heldout: Array
    thetas: Array

    @property
    def overall(self) -> float:
        """Geometric mean over runs of the held-out NRMSE (see :func:`typical`)."""
        return typical(self.heldout)

    def jackknife_se(self) -> Array:
        """Jackknife standard error of each θ coordinate over the folds."""
        n = self.thetas.shape[0]
        dev = self.thetas - self.thetas.mean(axis=0)
        return np.sqrt((n - 1) / n * np.sum(dev**2, axis=0))


def fold_state(full: FitState, leave: int, lengths: Sequence[int]) -> FitState:
    """The all-runs fit restricted to every run but ``leave`` (same θ, rows dropped)."""
    assert full.jac is not None
    keep = np.concatenate([np.full(lengths[i], i != leave) for i in full.runs])
    runs = tuple(i for i in full.runs if i != leave)
    return replace(full, runs=runs, res=full.res[keep], jac=full.jac[keep], lam=1e-3, done=False)


def cross_validate(fitter: BatchFitter, states: Sequence[FitState], *, rounds: int = FOLD_ROUNDS) -> list[CrossValidation]:
    """Leave-one-run-out cross-validation of every all-runs fit in ``states``."""
    lengths = fitter.lengths
    n = len(lengths)
    folds = [fold_state(s, i, lengths) for s in states for i in range(n)]
    folds = fitter.refine(folds, rounds=rounds, dampings=(1.0,), final_jacobian=False)
    jobs = [(f.candidate, f.theta, (k % n,)) for k, f in enumerate(folds)]
    res = fitter.residuals(jobs)
    out = []
    for j in range(len(states)):
        heldout = np.array([math.sqrt(sumsq(res[j * n + i])) for i in range(n)])
        out.append(CrossValidation(heldout, np.array([folds[j * n + i].theta for i in range(n)])))
    return out
