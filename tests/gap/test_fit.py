"""The batched Levenberg–Marquardt fitter: a Jacobian only where a step was accepted, and the same path."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from grader.datasets import load
from grader.gap import baseline, fit
from grader.gap.backend import Backend, stretches
from grader.gap.candidates import combine, make_candidates
from grader.gap.fit import BatchFitter, grid_starts
from grader.gap.objective import objective
from grader.gap.runs import prepare_runs, truncated
from grader.gap.search import search, second_effect

from .conftest import MakeDataset


def _fitter(make: MakeDataset) -> tuple[BatchFitter, list]:
    ds = load(make("coulomb_friction", {"coulomb_friction": {"Fc": 2.0}}))
    runs = [truncated(r, 0.3) for r in prepare_runs(ds, ds.given["sample_time"])[1]]
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


def test_an_addition_at_its_nesting_theta_simulates_as_the_first_effect_alone(make: MakeDataset) -> None:
    """Every addition with a magnitude, at the first's θ and its own neutral magnitude, is the first effect alone:
    the same positions, bit for bit. (A spool lag's neutral, its least fitted time constant of 0.1 ms, is not: at
    the margin of stability the instability run feels even that phase lag.)"""
    ds = load(make("coulomb_friction", {"coulomb_friction": {"Fc": 2.0}}))
    runs = [truncated(r, 0.3) for r in prepare_runs(ds, ds.given["sample_time"])[1]]
    base = baseline.choose(ds, runs, key=None, implied_kfb=None).params
    cands = {c.effect: c for c in make_candidates(base)}
    first = cands["coulomb_friction"]
    theta = np.array([0.05, -0.2, 0.01, 0.3])
    exact = [c for name, c in cands.items() if c.params and name not in (first.effect, "valve_dynamics")]
    pairs = [combine(first, c) for c in exact]
    assert len(pairs) == 4
    ys = Backend(runs).all_runs([first.point(base, theta), *(p.point(base, p.nesting(theta)) for p in pairs)])
    for pair, y in zip(pairs, ys[1:]):
        assert all(np.array_equal(a, b) for a, b in zip(y, ys[0])), pair.effect


def test_no_addition_ends_a_second_search_worse_than_the_first_effect_alone(make: MakeDataset) -> None:
    """Each addition nests the first effect (at its neutral magnitude), so none ends the pair search fitting worse than
    the first alone refitted there: one that does is started once more from where it nests the first."""
    ds = load(make("coulomb_friction", {"coulomb_friction": {"Fc": 2.0}}))
    runs = [truncated(r, 0.4) for r in prepare_runs(ds, ds.given["sample_time"])[1]]
    base = baseline.choose(ds, runs, key=None, implied_kfb=None).params
    cands = {c.effect: c for c in make_candidates(base, ["coulomb_friction", "sampling_delay", "valve_saturation"])}
    objs = [objective(r) for r in runs]
    first = search(objs, base, [cands["coulomb_friction"]]).states[0]
    found = second_effect(objs, base, first, [cands["sampling_delay"], cands["valve_saturation"]])
    assert [s.candidate.effect for s in found.states][-1] == "coulomb_friction"
    assert all(s.cost <= found.states[-1].cost for s in found.states[:-1])


def test_passes_split_by_their_budget_give_the_residuals_of_one_pass(make: MakeDataset,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Jobs simulated in passes of at most MAX_PASS_SAMPLES (a pass's positions are all held until its residuals are
    taken) give the residuals of a single pass, job by job, and no pass holds more than the budget; at the default
    budget, a lab's batch is one pass."""
    fitter, states = _fitter(make)
    every = tuple(range(len(fitter.runs)))
    jobs = [(s.candidate, s.theta + d, runs) for s in states for d in (0.0, 0.01, -0.02)
            for runs in (every, every[:1], every[1:])]
    passes: list[int] = []
    sim = fitter.sim
    monkeypatch.setattr(fitter, "sim", lambda requests: passes.append(sum(fitter.runs[i].n for _, i in requests))
                        or sim(requests))
    whole = fitter.residuals(jobs)
    assert len(passes) == 1
    passes.clear()
    budget = 2 * sum(r.n for r in fitter.runs)
    monkeypatch.setattr(fit, "MAX_PASS_SAMPLES", budget)
    split = fitter.residuals(jobs)
    assert len(passes) > 3 and max(passes) <= budget
    assert all(np.array_equal(a, b) for a, b in zip(split, whole, strict=True))


@given(st.lists(st.integers(1, 50), max_size=40), st.integers(1, 120))
def test_passes_cover_every_job_once_in_order(sizes: list[int], budget: int) -> None:
    """Each job in one pass, in order; each pass within the budget unless one job alone exceeds it, and as long as
    it can be: the next job would take it over."""
    passes = stretches(sizes, budget, padded=False)
    assert [k for s in passes for k in range(len(sizes))[s]] == list(range(len(sizes)))
    assert all(sizes[s] and (sum(sizes[s]) <= budget or len(sizes[s]) == 1) for s in passes)
    assert all(sum(sizes[s]) + sizes[s.stop] > budget for s in passes if s.stop < len(sizes))
