"""A second-order spool against a delay verdict.

``valve_dynamics`` is ranked as a first-order spool lag. A second-order spool of damping 0.7 (ωn = 1/tau: the
form of servo-valve data sheets, ``order=2`` in the effects' contract) is maximally flat: below ωn it acts on the
loop as a pure delay of 2·0.7·tau, which a first-order lag fits worse than a delay does. On 8 rigs simulated
through the solve_ivp path with such a spool, 7 verdicts were a delay, and the second-order spool fitted the runs
as well as the delay on 5 of them (within 0.06 of the floor's mean square); on 7 of benchmark run A's delays it
fitted within 0.01 of the delay. So where the verdict is a delay, the second-order spool is fitted too; where it
fits the runs better than the first-order lag, it is the ``valve_dynamics`` candidate, and the verdict is ranked
again: a spool the data cannot tell from the delay is listed as such. The verdict stays the delay (ranked freely,
the spool took 8 of run A's 25 delays on fits a hundredth of the floor apart; the default spool is first
order).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import replace

import numpy as np

from grader.gap.candidates import Candidate
from grader.gap.fit import FitState
from grader.gap.objective import RunObjective
from grader.gap.search import SearchResult, refit
from grader.model.effects import EFFECTS
from grader.model.params import RigParams

DELAY, SPOOL = "sampling_delay", "valve_dynamics"
#: The second-order form's held parameters; its damping is the effects' default (0.7).
SECOND_ORDER = {"order": 2.0, "zeta": EFFECTS[SPOOL].param("zeta").default}


#: The realistic range of a spool's tau [s] (small rigs' valves, docs/reference/effects.md): a spool faster than its
#: bottom is no lookalike of a delay (a second-order one acts as a delay of 1.4·τ below ωn, a first-order one of
#: about τ, so every delay under about 0.7 ms had a lookalike, and run A's delays of 0.3-0.6 ms were reported as not
#: told apart from one).
TYPICAL_TAU = EFFECTS[SPOOL].param("tau").typical


def fitted_tau(state: FitState) -> float:
    """The spool's tau [s] at a fit of the spool alone."""
    return state.candidate.values(state.theta)[SPOOL]["tau"]


def too_fast_note(tau: float, order: float) -> str:
    """The note on a spool of ``order`` that acts as the delay but is faster than the realistic range's."""
    form = "a second-order spool (damping 0.7)" if order == 2 else "a spool lag"
    return (f"{form} of tau = {tau * 1e3:.2g} ms would act on these runs as the delay "
            f"does, but it is faster than small rigs' servo valves ({TYPICAL_TAU[0] * 1e3:g}-{TYPICAL_TAU[1] * 1e3:g} "
            "ms): the delay is named; a step recorded at a faster sample rate would tell them apart")


def second_order(c: Candidate) -> Candidate:
    """The ``valve_dynamics`` candidate ``c`` (a first-order lag) as a second-order spool."""
    assert c.names == (SPOOL,), "only the spool alone has a second-order form"
    return replace(c, fixed={SPOOL: dict(SECOND_ORDER)})


def fit_against_delay(objs: Sequence[RunObjective], base: RigParams, delay: FitState, spool: FitState, *,
                      executor: Executor | None = None) -> SearchResult:
    """The second-order spool fitted to the runs (and cross-validated) from the delay's optimum: its linear
    coordinates, and the tau [s] whose low-frequency phase lag is the delay's (delay [s] = 2·zeta·tau)."""
    c = second_order(spool.candidate)
    p_delay, p_tau = delay.candidate.params[0], c.params[0]
    lead = delay.candidate.lead
    tau = float(delay.theta[lead]) * p_delay.scale / (2.0 * SECOND_ORDER["zeta"])
    lo, hi = c.bounds(base)
    theta = np.clip(np.concatenate([delay.theta[:lead], [tau / p_tau.scale]]), lo, hi)
    start = FitState(c, spool.runs, theta, spool.res)  # a fresh fit: the residual is recomputed there
    return refit(objs, base, start, executor=executor)
