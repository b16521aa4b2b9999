"""A second-order spool against a delay (or a first-order lag) verdict.

``valve_dynamics`` is ranked as a first-order spool lag. A second-order spool (ωn = 1/tau: the form of servo-valve
data sheets, ``order=2`` in the effects' contract) of damping near 0.7 is maximally flat: below ωn it acts on the
loop as a pure delay of 2·zeta·tau, which a first-order lag fits worse than a delay does; one whose corner lies
near the loop's frequencies acts as neither. On 8 rigs simulated through the solve_ivp path with such a spool, 7
verdicts were a delay, and the second-order spool fitted the runs as well as the delay on 5 of them (within 0.06
of the floor's mean square); on 7 of benchmark run A's delays it fitted within 0.01 of the delay. So where the
verdict is a delay or a first-order lag and both are candidates, the second-order spool is fitted too, its damping
over the realistic range (0.5 to 1); where it fits the runs better than the first-order lag, it is the
``valve_dynamics`` candidate, and the verdict is ranked again: a spool the data cannot tell from the delay is
listed as such. The verdict stays (ranked freely, the spool took 8 of run A's 25 delays on fits a hundredth of the
floor apart; the default spool is first order); the replayed runs then decide between them
(:mod:`grader.gap.replay`). With the damping held at 0.7 and the spool fitted only from a delay verdict's optimum,
11 of run A's 14 second-order spools (dampings 0.54 to 0.97, corners 40 to 294 Hz) were missed (named a delay, or
listed beside one); now 4, each named a delay or a spool with the other listed beside it (corners of 130 to
290 Hz).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import replace

import numpy as np

from grader.gap.candidates import Array, Candidate, FitParam
from grader.gap.fit import FitState
from grader.gap.objective import RunObjective
from grader.gap.search import SearchResult, refit, search_from
from grader.model.effects import EFFECTS
from grader.model.params import RigParams

DELAY, SPOOL = "sampling_delay", "valve_dynamics"
#: The second-order form's held parameter; its damping is fitted over the realistic range (:data:`DAMPING`).
SECOND_ORDER = {"order": 2.0}
#: Where the second-order form's damping starts: the effects' default (0.7), maximally flat.
START_ZETA = EFFECTS[SPOOL].param("zeta").default


#: The realistic range of a spool's tau [s] (small rigs' valves, docs/reference/effects.md): a spool faster than its
#: bottom is no lookalike of a delay (a second-order one acts as a delay of 2·zeta·τ below ωn, a first-order one of
#: about τ, so every delay under about 0.7 ms had a lookalike, and run A's delays of 0.3-0.6 ms were reported as not
#: told apart from one).
TYPICAL_TAU = EFFECTS[SPOOL].param("tau").typical
#: The least damping of the realistic range: the slowest second-order spool that acts as a given delay has it.
LEAST_ZETA = EFFECTS[SPOOL].param("zeta").typical[0]
#: The second-order form's damping, fitted over the realistic range (0.5 to 1). Held at 0.7, a spool of damping 0.54
#: and a 51 Hz corner (run A's 0100) fitted the runs worse than a delay, and the replayed runs 126 worse.
DAMPING = FitParam(SPOOL, "zeta", "dimensionless", 1.0, LEAST_ZETA, EFFECTS[SPOOL].param("zeta").typical[1],
                   LEAST_ZETA)


def fitted(state: FitState) -> dict[str, float]:
    """The spool's parameters (tau [s], order, zeta) at a fit of the spool alone."""
    return state.candidate.values(state.theta)[SPOOL]


def slowest_tau(tau: float, order: float, zeta: float) -> float:
    """The largest tau [s] of a realistic spool of ``order`` that acts as the fitted one (``tau``, damping ``zeta``)
    does: a first-order lag's own; a second-order spool's at the least realistic damping (:data:`LEAST_ZETA`),
    whose low-frequency lag 2·zeta·tau is the fitted one's. On an independent simulator's rig, a spool of 233 Hz and
    damping 0.5, inside the realistic range, acted as a delay of 0.63 ms, which a damping of 0.7 put at 355 Hz."""
    return tau * zeta / LEAST_ZETA if order == 2 else tau


def too_fast_note(tau: float, order: float, zeta: float) -> str:
    """The note on a spool of ``order`` (damping ``zeta``) that acts as the delay but is faster than the realistic
    range's, even at the least realistic damping."""
    form = f"a second-order spool (damping {zeta:.2g})" if order == 2 else "a spool lag"
    least = (f", or {slowest_tau(tau, order, zeta) * 1e3:.2g} ms at damping {LEAST_ZETA:g},"
             if order == 2 and zeta > LEAST_ZETA else "")
    return (f"{form} of tau = {tau * 1e3:.2g} ms{least} would act on these runs as the delay "
            f"does, but it is faster than small rigs' servo valves ({TYPICAL_TAU[0] * 1e3:g}-{TYPICAL_TAU[1] * 1e3:g} "
            "ms): the delay is named; a step recorded at a faster sample rate would tell them apart")


def second_order(c: Candidate) -> Candidate:
    """The candidate ``c`` whose last effect is ``valve_dynamics`` (a first-order lag; alone, or on top of a
    verdict) with that spool as a second-order spool: its damping fitted too."""
    assert c.names[-1] == SPOOL and c.names.count(SPOOL) == 1, "only a spool added last has a second-order form"
    return replace(c, params=(*c.params, DAMPING), fixed={**c.fixed, SPOOL: dict(SECOND_ORDER)})


#: Dampings the second-order form's searched starts take, with each start of its tau grid.
START_DAMPINGS = (0.55, START_ZETA, 0.9)


def fit_against_delay(objs: Sequence[RunObjective], base: RigParams, delay: FitState, spool: FitState, *,
                      head: Array | None = None, executor: Executor | None = None) -> SearchResult:
    """The second-order spool fitted to the runs (and cross-validated) in place of ``spool`` (a first-order lag,
    alone or added on top of a verdict whose optimum is ``head``, θ's coordinates before the spool's; None: alone),
    the better of two fits: from the optimum of ``delay`` (the same candidate with a delay in the spool's place: its
    other coordinates, a damping of :data:`START_ZETA`, and the tau [s] whose low-frequency phase lag is the
    delay's, delay = 2·zeta·tau), and the best of those searched as an effect is from each tau of the first-order
    lag's grid (its best damping of :data:`START_DAMPINGS` on the short windows). From the delay's optimum alone,
    the two rounds of a refit left run A's 0112 (a 131 Hz spool of damping 0.62, which the delay took for 5.5 ms)
    where it started, 30 times the delay's cost."""
    c = second_order(spool.candidate)
    p_delay, p_tau = delay.candidate.params[-1], c.params[-2]
    tau = float(delay.theta[-1]) * p_delay.scale / (2.0 * START_ZETA)
    lo, hi = c.bounds(base)
    theta = np.clip(np.concatenate([delay.theta[:-1], [tau / p_tau.scale, START_ZETA / DAMPING.scale]]), lo, hi)
    start = FitState(c, spool.runs, theta, spool.res)  # a fresh fit: the residual is recomputed there
    near = refit(objs, base, start, executor=executor)
    first = np.zeros(c.lead) if head is None else np.asarray(head, dtype=float)
    grid = [np.concatenate([first, [m, z / DAMPING.scale]]) for m in p_tau.grid() for z in START_DAMPINGS]
    searched = search_from(objs, base, c, grid, [k // len(START_DAMPINGS) for k in range(len(grid))],
                           executor=executor)
    return min(near, searched, key=lambda r: r.states[0].cost)
