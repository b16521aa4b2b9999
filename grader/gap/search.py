"""The candidate search: fit every candidate, then cross-validate.

Oscillating runs make the objective multimodal: a model whose frequency is off by a
few per cent drifts half a period out of phase over the ringing of a step near the
critical gain (the instability run's long oscillation is compared without its phase,
:mod:`grader.gap.objective`). So the search continues from short to long: first a
profile (β/Vt and Kce fitted at each magnitude of a grid over the effect's realistic
range) on the runs' first :data:`PROFILE_WINDOW` seconds after their command, then all
coordinates on their first :data:`FIRST_WINDOW` seconds, then on the whole runs; then
leave-one-run-out cross-validation.

Where the instability run's oscillation grows slowly toward its limit, its growth hangs on the
loop's damping within a per cent of Kce: a model a little too damped decays and costs the whole
oscillation, and there the objective is flat, so Levenberg–Marquardt cannot climb back. A fit whose
whole-run end costs more than :data:`CLIFF` times what its start cost on the first
:data:`FIRST_WINDOW` seconds has fallen off that cliff; it starts once more from that start with
ln Kce moved to the best of a fine line (:data:`CLIFF_LINE`), evaluated on the whole runs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from grader.gap.backend import Backend
from grader.gap.candidates import NONE, WEAK_STRENGTH, Candidate, combine
from grader.gap.crossval import CrossValidation, cross_validate
from grader.gap.fit import BatchFitter, FitState, grid_starts
from grader.gap.lm import sumsq
from grader.gap.objective import RunObjective
from grader.model.params import RigParams

Array = NDArray[np.float64]
PROFILE_WINDOW, FIRST_WINDOW = 0.25, 0.5  # [s] after each run's command, in the first stages
PROFILE_ROUNDS, FIRST_ROUNDS, FULL_ROUNDS = 3, 3, 2
#: A whole-run fit ending at more than CLIFF times the cost (Σ over runs of NRMSE², dimensionless) its start had on
#: the first FIRST_WINDOW seconds fell off the instability run's cliff; it is started again from that start with
#: ln Kce moved by the best offset of CLIFF_LINE (Kce within ±20 % in steps of 1 %; module docstring).
CLIFF = 10.0
CLIFF_LINE = tuple(round(0.01 * i, 2) for i in range(-20, 21))
#: Levenberg–Marquardt rounds of the fits that free the valve's null from their optima without it (:func:`search`).
NULL_ROUNDS = 4
#: Starts :func:`screened` fits, of those it evaluates.
SCREEN_KEEP = 3


@dataclass(frozen=True)
class SearchResult:
    """All-runs fits and their cross-validations, in candidate order; ``lengths`` are the residual entries
    of each run in the states' stacked residuals; ``dropped``: the fits a search's ``keep`` left out, in
    candidate order (not cross-validated)."""

    states: list[FitState]
    cvs: list[CrossValidation]
    lengths: list[int]
    dropped: list[FitState] = field(default_factory=list)


def _fitter(objectives: Sequence[RunObjective], base: RigParams, window: float | None,
            executor: Executor | None) -> BatchFitter:
    """A fitter on the runs cut to ``window`` seconds after their command (None: whole)."""
    cut = [o.cut(window) for o in objectives]
    return BatchFitter(cut, base, Backend([o.run for o in cut], executor=executor))


def _with_linear(states: Sequence[FitState], which: Sequence[int], lin: Array) -> list[FitState]:
    """``states[k]`` for each k of ``which`` with its linear coordinates (and fitted null) set to ``lin`` (its
    magnitudes kept)."""
    return [replace(states[k], theta=np.concatenate([lin, states[k].theta[lin.size:]])) for k in which]


#: Which of a search's fitted states (given the runs' lengths) are worth cross-validating; the rest are left out.
Keep = Callable[[Sequence[FitState], Sequence[int]], Sequence[bool]]


def search(objectives: Sequence[RunObjective], base: RigParams, candidates: Sequence[Candidate], *,
           executor: Executor | None = None, theta0: Sequence[Array] | None = None,
           keep: Keep | None = None, null_scale: float | None = None) -> SearchResult:
    """Fit ``candidates`` around ``base`` on the runs of ``objectives`` and cross-validate them (see module
    docstring); ``theta0`` are the profile's starting points (default: the baseline, zero magnitudes); with them,
    the search is a second search (:func:`second_effect`): the last candidate is the first effect alone, which
    every other one extends. With ``keep``, only the fits it keeps are cross-validated and returned, in order (the
    others in ``dropped``). With ``null_scale`` [mA] (a first search), every fit is then fitted once more with the
    valve's null free (:meth:`Candidate.with_null`), over :data:`NULL_ROUNDS` rounds from its optimum without it:
    none ends worse than it was, and the null moves where the runs ask for it.

    Every whole-run fit starts twice, keeping the better end: from where the short windows led it and from
    the baseline's linear coordinates (for a second effect, the first effect's optimum's), since a profile can
    lead an effect astray (a spool lag into a slower mode that then holds the fit). In a first search, a fit
    that still ends worse than ``none``, which nests in every effect at zero magnitude, starts once more from
    ``none``'s optimum. In a second search, an addition that ends worse than the first alone starts once more
    where it nests the first: the first's optimum, the addition at its neutral magnitude (a delay started at the
    profile's magnitude can put the instability run's model in another regime, which then holds the fit). Before
    both, a fit that fell off the instability run's cliff starts once more from a fine line in ln Kce (module
    docstring)."""
    short, middle, full = (_fitter(objectives, base, w, executor) for w in (PROFILE_WINDOW, FIRST_WINDOW, None))
    states = short.profile(*grid_starts(candidates, theta0), rounds=PROFILE_ROUNDS)
    states = middle.fit(middle.rebase(states), rounds=FIRST_ROUNDS, final_jacobian=False)
    n = len(states)
    lead = candidates[0].lead  # the linear coordinates, and the null's where it is fitted: alike in every candidate
    lin0 = np.zeros(lead) if theta0 is None else np.asarray(theta0[-1], dtype=float)[:lead]
    ends = full.fit(full.rebase([*states, *_with_linear(states, range(n), lin0)]), rounds=FULL_ROUNDS)
    ends = [min(ends[k], ends[n + k], key=lambda s: s.cost) for k in range(n)]
    cliff = [k for k in range(n) if ends[k].cost > CLIFF * states[k].cost]
    if cliff:
        lined = full.line([(states[k].candidate, states[k].theta) for k in cliff], offsets=CLIFF_LINE, whole=True)
        for k, s in zip(cliff, full.fit(full.rebase(lined), rounds=FULL_ROUNDS)):
            ends[k] = min(ends[k], s, key=lambda x: x.cost)
    if theta0 is None:
        ref = next((k for k, s in enumerate(ends) if s.candidate.effect == NONE), None)
        if ref is not None:
            ends[ref] = _none_from_neutral(full, ends, ref)
        redo = [] if ref is None else [k for k, s in enumerate(ends) if s.cost > ends[ref].cost]
        restarts = _with_linear(states, redo, ends[ref].theta[:lead]) if redo else []
    else:
        redo = [k for k, s in enumerate(ends[:-1]) if s.cost > ends[-1].cost]
        restarts = [replace(states[k], theta=states[k].candidate.nesting(ends[-1].theta), jac=None) for k in redo]
    if redo:
        again = full.fit(full.rebase(restarts), rounds=FULL_ROUNDS)
        for k, s in zip(redo, again):
            ends[k] = min(ends[k], s, key=lambda x: x.cost)
    if null_scale:
        assert theta0 is None, "the null is freed in a first search; a second one extends fits that have it"
        freed = [(s, *s.candidate.with_null(null_scale, s.theta)) for s in ends]
        ends = full.fit(full.rebase([FitState(c, s.runs, th, s.res) for s, c, th in freed]), rounds=NULL_ROUNDS)
    dropped: list[FitState] = []
    if keep is not None:
        kept = keep(ends, full.lengths)
        ends, dropped = [s for s, k in zip(ends, kept) if k], [s for s, k in zip(ends, kept) if not k]
    return SearchResult(ends, cross_validate(full, ends), full.lengths, dropped)


def _none_from_neutral(full: BatchFitter, ends: list[FitState], ref: int) -> FitState:
    """``none``'s fit (``ends[ref]``), started once more from the linear coordinates of the best effect that ended
    below it barely acting (strength below :data:`~grader.gap.candidates.WEAK_STRENGTH`, its neutral magnitude
    included): that effect is ``none`` at a better optimum, or next to one. An independent simulator's rig with no
    effect had Coulomb friction at Fc = 0 fit the runs 2.6 times better than ``none``, which let a spool lag at its
    least fitted value be named; with the valve's null held in the runs, another had ``none`` fit 2.6 times worse
    than Coulomb friction at Fc = 0.013 lbf, which was named. Started there, ``none`` fit as well as either."""
    weak = [s for s in ends if s.candidate.params and s.cost < ends[ref].cost
            and s.candidate.strength(s.theta) < WEAK_STRENGTH]
    if not weak:
        return ends[ref]
    start = min(weak, key=lambda s: s.cost)
    none = ends[ref]
    again = full.fit(full.rebase([replace(none, theta=np.asarray(start.theta[:none.candidate.lead]), jac=None,
                                          done=False)]),
                     rounds=FULL_ROUNDS)[0]
    return min(none, again, key=lambda s: s.cost)


def search_from(objectives: Sequence[RunObjective], base: RigParams, candidate: Candidate, starts: Sequence[Array],
                owner: Sequence[int], *, executor: Executor | None = None) -> SearchResult:
    """``candidate`` fitted from each θ of ``starts`` through :func:`search`'s first stages (its linear coordinates
    fitted on the short windows with its magnitudes held, the best start of each ``owner`` kept, then all
    coordinates on the longer window and the whole runs), without its restarts (from the baseline's linear
    coordinates, off the cliff, from ``none`` or a nesting optimum); the best end, cross-validated."""
    short, middle, full = (_fitter(objectives, base, w, executor) for w in (PROFILE_WINDOW, FIRST_WINDOW, None))
    states = short.profile([(candidate, np.asarray(s, dtype=float)) for s in starts], owner, rounds=PROFILE_ROUNDS)
    return _onward(middle, full, states)


def _onward(middle: BatchFitter, full: BatchFitter, states: Sequence[FitState]) -> SearchResult:
    """``states`` fitted on the ``middle`` fitter's window, then on the whole runs (``full``); the best end,
    cross-validated."""
    states = middle.fit(middle.rebase(states), rounds=FIRST_ROUNDS, final_jacobian=False)
    best = min(full.fit(full.rebase(states), rounds=FULL_ROUNDS), key=lambda s: s.cost)
    return SearchResult([best], cross_validate(full, [best]), full.lengths)


def refit(objectives: Sequence[RunObjective], base: RigParams, start: FitState, *,
          executor: Executor | None = None) -> SearchResult:
    """``start``'s candidate fitted on the whole runs from ``start``'s θ (no profile, no restarts) and
    cross-validated."""
    full = _fitter(objectives, base, None, executor)
    end = full.fit(full.rebase([replace(start, jac=None, done=False, n_free=None)]), rounds=FULL_ROUNDS)
    return SearchResult(end, cross_validate(full, end), full.lengths)


def screened(objectives: Sequence[RunObjective], base: RigParams, starts: Sequence[FitState], *,
             executor: Executor | None = None, keep: int = SCREEN_KEEP) -> SearchResult:
    """``starts`` (one candidate's θs) evaluated once on the runs' first :data:`FIRST_WINDOW` seconds; the ``keep``
    best fitted there and then on the whole runs, as :func:`search_from` fits its profile's ends; the best end,
    cross-validated."""
    middle, full = (_fitter(objectives, base, w, executor) for w in (FIRST_WINDOW, None))
    every = tuple(range(len(objectives)))
    res = middle.residuals([(s.candidate, s.theta, every) for s in starts])
    order = sorted(range(len(starts)), key=lambda k: (sumsq(res[k]), k))[:keep]
    return _onward(middle, full, [FitState(starts[k].candidate, every, starts[k].theta, res[k]) for k in order])


def second_effect(objectives: Sequence[RunObjective], base: RigParams, first: FitState, others: Sequence[Candidate], *,
                  executor: Executor | None = None, keep: Keep | None = None) -> SearchResult:
    """Each of ``others`` added on top of the fitted ``first`` (greedy), searched from first's optimum;
    the first alone comes back as the last entry, the reference the additions must beat (``keep`` must keep
    it: see :func:`search`)."""
    combos = [combine(first.candidate, o) for o in others]
    starts = [np.concatenate([first.theta, np.zeros(c.n_theta - first.theta.size)]) for c in combos]
    return search(objectives, base, [*combos, first.candidate], executor=executor, theta0=[*starts, first.theta],
                  keep=keep)

