"""A verdict's lookalikes checked again beside the second effect named on top of it.

The ranking of single effects lists as the verdict's ties the effects that fit the runs as well as it alone. Alone,
a tie may have stood in for part of the second effect's share of the gap rather than for the verdict: an
independent simulator's deadband with a current limit on top kept a spool lag which, with the limit on top, fitted
all runs 48 times worse and scored 11 times worse held out; run A's (seed 300) 0277, the same pair, kept Coulomb
friction, 317 and 30 times worse. So once a pair is named, :func:`untied` puts each tie in the verdict's place with
the same addition on top and keeps it only where that pair fits as well as the named one, in the closed loop by the
rule of a lookalike, and then on the replayed runs (:mod:`grader.gap.replay`), which tell the pairs apart where they
decide: an independent simulator's deadband with a delay on top kept Coulomb friction in the closed loop, which fits
all runs 8 % better in the deadband's place, and the replayed runs follow the deadband's pair better by 1,965.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from grader.gap import baseline as baseline_mod
from grader.gap import replay
from grader.gap.candidates import Candidate, split_last
from grader.gap.fit import FitState
from grader.gap.objective import RunObjective
from grader.gap.pairs import Second, scored_of
from grader.gap.schema import ReplayInfo
from grader.gap.search import SearchResult, refit, second_effect
from grader.gap.verdict import ACTING, TIE, TIE_FIT, scores

__all__ = ["untied"]

Array = NDArray[np.float64]
#: ``ReplayInfo.of`` of the replay of the verdict's pair against its ties' pairs.
OF = "verdict_with_second_effect"


def untied(objs: Sequence[RunObjective], base: baseline_mod.Baseline, found: SearchResult, verdict: int,
           ties: Sequence[int], extra: Second, floor_nrmse: Array, sigma: float,
           executor: Executor | None) -> tuple[list[int], list[ReplayInfo], str]:
    """The verdict's ties (indices into ``found``, the single-effect search) that stay its lookalikes once ``extra``
    is named on top of it, the replay that judged them (none or one entry) and why ('' where nothing was said).

    The effect named on top is no doubt of the verdict. Any other tie is put in the verdict's place with the same
    addition on top (:func:`_in_place`) and stays where it still acts there (:data:`~grader.gap.verdict.ACTING`)
    and the data cannot tell that pair from the named one: in the closed loop by the rule of a lookalike
    (:func:`grader.gap.verdict.lookalikes`: within TIE held out, or within TIE_FIT of the floor ``floor_nrmse``
    leaves in all-runs mean square), and then, where every run recorded its controller output, on the replayed runs
    (reading noise ``sigma`` [in]) unless they decide and tell the pair apart from the named one."""
    first, second = split_last(extra.state.candidate)
    added = second.effect
    named, floor = extra.scored, TIE_FIT * float(np.mean(floor_nrmse**2))
    kept, fits, gone = [], [], []
    for i in ties:
        tie = found.states[i]
        if tie.candidate.names[-1] == added:
            continue
        alt = _in_place(objs, base, tie, second, extra.state.theta[first.n_theta:], executor)
        sc = scored_of(alt)[0]
        s = scores([named, sc])
        acts = tie.candidate.strength(alt.states[0].theta[:tie.candidate.n_theta]) >= ACTING
        if acts and (np.log(s[1] / s[0]) < TIE or sc.fit_ms - named.fit_ms < floor):
            kept.append(i)
            fits.append(alt.states[0])
        else:
            gone.append(i)
    names = [s.candidate.effect for s in found.states]
    why = (f"in {names[verdict]}'s place with {added} on top, {', '.join(names[i] for i in gone)} "
           f"fit{'s' if len(gone) == 1 else ''} the runs clearly worse" if gone else "")
    runs = [o.run for o in objs]
    if not kept or not replay.replayable(runs):
        return kept, [], why
    rp = replay.compare(runs, base.params, [extra.state, *fits], range(len(kept) + 1), sigma, executor=executor)
    told = [i for k, i in enumerate(kept, 1) if rp.decides and rp.excess[k] - rp.excess[0] >= replay.EVIDENCE]
    left = [names[i] for i in kept if i not in told]
    said = (f"the runs tell {names[verdict]} apart from {', '.join(names[i] for i in told)}" if told else
            f"the runs do not tell {names[verdict]} apart from {', '.join(left)} either" if rp.decides else "")
    if said:
        why = "; ".join(w for w in (why, f"{replay.REPLAYED}, with {added} on top, {said}") if w)
    info = replay.info(rp, [names[verdict], *(names[i] for i in kept)], OF)
    return [i for i in kept if i not in told], [info], why


def _in_place(objs: Sequence[RunObjective], base: baseline_mod.Baseline, tie: FitState, second: Candidate,
              added: Array, executor: Executor | None) -> SearchResult:
    """The pair of ``tie`` (a single effect's fit) with ``second`` on top, the better of two fits: searched from the
    tie's optimum as the pair search adds an effect (:func:`grader.gap.search.second_effect`), and fitted from
    there with the addition where the named pair's ended (``added``, its coordinates of θ): a spool lag on top,
    searched from a poor start, can end worse than the tie alone (:func:`grader.gap.pairs._lag_from_line`)."""
    searched = second_effect(objs, base.params, tie, [second], executor=executor)
    combo = searched.states[0].candidate
    start = replace(tie, candidate=combo, theta=np.concatenate([tie.theta, added]))
    near = refit(objs, base.params, start, executor=executor)
    return min(near, searched, key=lambda r: r.states[0].cost)
