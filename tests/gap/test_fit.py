"""The batched Levenberg–Marquardt fitter: a Jacobian only where a step was accepted, and the same path."""

from __future__ import annotations

import numpy as np

from grader.datasets import load
from grader.gap import baseline
from grader.gap.backend import Backend
from grader.gap.candidates import make_candidates
from grader.gap.fit import BatchFitter, grid_starts
from grader.gap.objective import objective
from grader.gap.runs import prepare_runs, truncated

from .conftest import MakeDataset


def _fitter(make: MakeDataset) -> tuple[BatchFitter, list]:
    ds = load(make("coulomb_friction", {"coulomb_friction": {"Fc": 2.0}}))
    runs = [truncated(r, 0.3) for r in prepare_runs(ds, ds.given["sample_time"])]
    base = baseline.choose(ds, runs, key=None, implied_kfb=None)
    cands = make_candidates(base.params, ["coulomb_friction", "sampling_delay"])
    fitter = BatchFitter([objective(r) for r in runs], base.params, Backend(runs))
    starts = fitter.profile(*grid_starts(cands), rounds=1)
    return fitter, fitter.rebase(starts)


def test_jacobians_end_at_the_final_theta_and_skipping_the_last_changes_no_step(make: MakeDataset) -> None:
    fitter, states = _fitter(make)
    with_jac = fitter.fit(states, rounds=2)
    without = fitter.fit(states, rounds=2, final_jacobian=False)
    fresh = fitter.rebase(with_jac)
    for a, b, f in zip(with_jac, without, fresh):
        assert np.array_equal(a.theta, b.theta) and np.array_equal(a.res, b.res)
        assert a.jac is not None and np.array_equal(a.jac, f.jac)  # the Jacobian at the final θ, as if new
        assert b.jac is None or np.array_equal(b.jac, a.jac)  # None only where the last step moved θ
    assert any(not np.array_equal(a.theta, s.theta) for a, s in zip(with_jac, states))  # the fit did move
    assert all(a.cost <= s.cost for a, s in zip(with_jac, states))  # and never up
