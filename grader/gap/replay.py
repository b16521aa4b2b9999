"""Lookalike effects told apart by replaying the controller output the rig recorded.

In the closed loop, the rig's controller reads its own reading noise, and the rig moves with it: at a gain
near the critical one, that motion is a lightly damped oscillation the model cannot know. It concentrates on a
few dozen cycles, so two effects that act alike at the loop's frequencies (a delay and a spool lag of a
millisecond, Coulomb friction and a valve deadband) trade places on a fit of the runs by chance: on benchmark run
A's 0114 (a 1.1 ms spool lag), a delay fitted the closed-loop runs 3 % of the noise's mean square better than the
spool lag at its true value, against 0.6 % the other way without noise.

Replayed, the model is driven by the controller output of the ``u`` column instead of its own controller
(:class:`grader.gap.backend.Backend` with ``replay``), so it follows the rig's own path, its noise-driven motion
included, and what is left of a right model is the reading noise, sample by sample. The verdict, the candidates
the closed-loop runs could not tell from it and every other effect that explains clearly more than ``none`` and
scores within :data:`SPAN` of it (and, on top of the verdict, a second effect, its lookalikes and the other
additions that pass the bar and score within SPAN of it; or, where none passes it, every addition:
:func:`grader.gap.pairs.pick_second`) are fitted again to the replayed runs from their closed-loop optima (their
linear parameters and their own), each run with a position offset and a drift of its own (open loop, where the rig
started shifts the whole run, and a valve null offset, which the rig's controller held against, integrates to a
constant velocity: with 0.05 V added to every recorded output of run A's 0104, the replay still named the spool
lag, while without the drift 2 mV stopped it). Their sums of squares are compared in units of the best one's mean
square per sample: ``excess = (SS − SS_best) / (SS_best / N)``, a likelihood ratio's 2·ln on white noise.

Two candidates whose excesses differ by :data:`EVIDENCE` or more are told apart. The verdict moves to the best
only where the verdict is told apart from it, and where the best replayed fit is itself good (a mean square per
sample at most :data:`GOOD` times the reading noise's): a rig the open-loop model cannot follow decides nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from grader.gap import hum
from grader.gap.backend import Backend
from grader.gap.build import r6
from grader.gap.fit import BatchFitter, FitState
from grader.gap.runs import GapRun
from grader.gap.schema import ReplayInfo
from grader.gap.summary import by_text
from grader.gap.verdict import Ranking
from grader.model.params import RigParams

Array = NDArray[np.float64]
#: Excess (2·ln of a likelihood ratio) at which a replayed fit tells two candidates apart: "strong" evidence on
#: Kass and Raftery's scale. On run A (seed 300), a delay's tied second-order spool (damping 0.7: below its corner,
#: a delay of 1.4·tau) fitted the replayed runs 2.1 and 2.4 better than the delay on 2 of 25 delays, while a spool
#: lag the closed loop took for a delay (0104) fitted 16.5 better, and Coulomb friction the closed loop took for a
#: deadband 48 to 420 better.
EVIDENCE = 6.0
#: Best replayed fit's mean square per sample, in units of the reading noise's, above which the replay decides
#: nothing (run A's delays and spool lags: 0.4 to 1.08).
GOOD = 1.5
#: Levenberg–Marquardt rounds from the closed-loop optimum.
ROUNDS = 8
#: Largest log ratio of held-out scores to the verdict's (or to the second effect's) at which another effect that
#: explains clearly more is replayed too: within a factor e. The replay named effects that scored up to 0.3 worse in
#: the closed loop on run A; replaying every effect that explains clearly more cost a fifth of an analysis on ten
#: of its datasets (a valve saturation: 0.8 s, to tell it from an orifice law the closed loop had already put 3
#: orders of magnitude behind).
SPAN = 1.0


@dataclass(frozen=True)
class ReplayObjective:
    """A run compared open loop: the model's positions x_k [in] against the readings y_k, less what fits their
    difference best among a straight line in time (where the rig started, and the constant velocity that a valve null
    offset the model lacks integrates to) and the mains ``lines`` [Hz] the runs' rests show (:mod:`grader.gap.hum`),
    in units of the reading noise ``sigma`` [in]. The rig's controller reads the hum and the recorded output carries
    its answer, which drives the model; the hum itself is in the readings only, where a model whose response at the
    hum differs from the rig's can cancel part of it: on an independent simulator's rig with a second-order spool and
    60 Hz pickup as large as the reading noise, a delay fitted the replayed runs 6.6 better (in 2·ln likelihood) than
    the spool, and 0.1 worse without the pickup."""

    run: GapRun
    sigma: float
    lines: tuple[float, ...] = ()

    @property
    def length(self) -> int:
        return self.run.n

    @cached_property
    def _basis(self) -> Array:
        return hum.basis(self.run.t, self.lines)

    def residual(self, x: Array) -> Array:
        d = x - self.run.y
        q = self._basis
        d = d - np.sum(q * np.sum(q * d[:, None], axis=0), axis=1)
        return d / self.sigma


@dataclass(frozen=True)
class Replay:
    """Replayed fits of candidates (by index into the caller's list): each one's excess over the best (that of the
    form that stands for it, where it was fitted in several: :func:`scored`) and which of the states compared that
    form was, the best's index and its mean square per sample in units of the reading noise's."""

    indices: tuple[int, ...]
    excess: tuple[float, ...]
    form: tuple[int, ...]
    best: int
    quality: float

    @property
    def decides(self) -> bool:
        """Whether the best replayed fit is good enough to decide anything (:data:`GOOD`)."""
        return self.quality <= GOOD

    def apart(self, i: int, j: int) -> bool:
        """Whether candidates ``i`` and ``j`` fit the replayed runs :data:`EVIDENCE` or more apart."""
        return abs(self.excess[self.indices.index(i)] - self.excess[self.indices.index(j)]) >= EVIDENCE

    def pick(self, verdict: int) -> int:
        """The verdict the replay supports: the best where it tells ``verdict`` apart from it and decides."""
        return self.best if self.decides and self.apart(verdict, self.best) else verdict

    def kept(self, verdict: int, ties: Sequence[int]) -> list[int]:
        """The ``ties`` the replay does not tell apart from ``verdict`` (all where it decides nothing)."""
        return [i for i in ties if not (self.decides and i in self.indices and self.apart(i, verdict))]


REPLAYED = "replayed through the controller output the rig recorded"


def _why(names: Sequence[str], rp: Replay, old: int, v: int, tied: Sequence[int], gone: Sequence[int],
         what: str, added: Sequence[int] = ()) -> str:
    """What the replay changed: a new pick, ties told apart, lookalikes it added (``added``), or ties it could not
    break ('' where there were none)."""
    also = f", and not from {', '.join(names[i] for i in added)}" if added else ""
    if v != old:
        by = rp.excess[rp.indices.index(old)] - rp.excess[rp.indices.index(v)]
        text = (f"{REPLAYED}, {names[v]}{what} follows the runs better than {names[old]} (by {by_text(by)} in 2·ln "
                "likelihood), so it is named instead")
        others = [names[i] for i in gone if i != old]
        return text + (f", and tells it apart from {', '.join(others)}" if others else "") + also
    if gone:
        return f"{REPLAYED}, the runs tell {names[v]} apart from {', '.join(names[i] for i in gone)}{also}"
    if added:
        return f"{REPLAYED}, the runs do not tell {names[v]} apart from {', '.join(names[i] for i in tied)}"
    return f"{REPLAYED}, the runs do not tell them apart either" if tied else ""


def ranking(rk: Ranking, names: Sequence[str], rp: Replay, never: Sequence[int] = ()) -> tuple[Ranking, str]:
    """``rk`` with the replay's pick as the verdict (runner-up the old verdict, margin and confidence 0: the
    closed-loop runs do not name it), without the ties it tells apart and with every replayed candidate it does not
    tell apart from the pick (the closed loop told them apart by the noise-driven motion it cannot follow: an
    independent simulator's 1.8 ms delay, which a second-order spool fitted the closed-loop runs clearly better, was
    named a spool outright though the replayed runs followed the delay 4.8 better), except ``never`` (a spool too
    fast to be a small rig's valve: neither a lookalike nor the pick), and why ('' where it decides nothing or
    changes nothing)."""
    if not rp.decides:
        return rk, ""
    old, pick = rk.verdict, rp.pick(rk.verdict)
    v = old if pick in never else pick
    ties = rp.kept(v, [i for i in dict.fromkeys([old, *rk.ties, *rp.indices]) if i != v and i not in never])
    gone = [i for i in [old, *rk.ties] if i != v and i not in ties]
    added = [i for i in ties if i not in (old, *rk.ties)]
    if v != old:
        rk = replace(rk, order=[v, *(i for i in rk.order if i != v)], verdict=v, runner_up=old, margin=0.0,
                     confidence=0.0, ties=ties)
    else:
        rk = replace(rk, ties=ties)
    return rk, _why(names, rp, old, v, rk.ties, gone, "", added)


def second(runs: Sequence[GapRun], base: RigParams, fits: Sequence[tuple[str, FitState]], tied: Sequence[int],
           sigma: float, *, executor: Executor | None = None) -> tuple[int, list[int], Replay, str]:
    """A second effect and its rivals (``fits``: the pick first, then the others that pass the bar, each on top of
    the verdict; ``tied``: those the closed loop could not tell from the pick) compared on the replayed runs: the one
    the replay supports, the pick and the tied ones it does not tell apart from that one, the replay, and why ('' where
    it decides nothing)."""
    names, every = [n for n, _ in fits], list(range(len(fits)))
    rp = compare(runs, base, [s for _, s in fits], every, sigma, executor=executor)
    if not rp.decides:
        return 0, list(tied), rp, ""
    v = rp.pick(0)
    before = [0, *tied]
    kept = rp.kept(v, [i for i in before if i != v])
    return v, kept, rp, _why(names, rp, 0, v, tied, [i for i in before if i != v and i not in kept], " on top")


def replayable(runs: Sequence[GapRun]) -> bool:
    """Whether every run recorded its controller output (finite)."""
    return all(r.u is not None and bool(np.all(np.isfinite(r.u))) for r in runs)


def compare(runs: Sequence[GapRun], base: RigParams, states: Sequence[FitState], indices: Sequence[int],
            sigma: float, *, executor: Executor | None = None) -> Replay:
    """``states`` (all-runs fits of candidates ``indices``; a candidate may come in several forms, a spool of
    first and of second order, its default form first) fitted again to the replayed ``runs`` from where they are,
    and compared (module docstring); a candidate's other form stands for it only where it fits :data:`EVIDENCE`
    better than the default; ``sigma`` [in] is the reading noise."""
    ends = refitted(runs, base, states, sigma, executor=executor)
    return scored([s.cost for s in ends], indices, sum(r.n for r in runs))


def refitted(runs: Sequence[GapRun], base: RigParams, states: Sequence[FitState], sigma: float, *,
             executor: Executor | None = None) -> list[FitState]:
    """``states`` fitted again to the replayed ``runs`` from where they are (:data:`ROUNDS` rounds), each run cleared of
    the mains lines the runs' rests show (:func:`grader.gap.hum.lines`); each end's cost is its sum of squares in
    units of the reading noise's variance (``sigma`` [in])."""
    found = hum.lines(runs)
    fitter = BatchFitter([ReplayObjective(r, sigma, found) for r in runs], base,
                         Backend(runs, executor=executor, replay=True))
    start = fitter.rebase([replace(s, jac=None, done=False, n_free=None) for s in states])
    return fitter.fit(start, rounds=ROUNDS, final_jacobian=False)


def scored(ss: Sequence[float], indices: Sequence[int], n: int) -> Replay:
    """The replay of fits whose sums of squares are ``ss`` (in units of the reading noise's variance) over ``n``
    samples, of candidates ``indices`` (a candidate's default form first): each candidate stands by its default
    form unless another of its forms fits :data:`EVIDENCE` better."""
    per = min(ss) / n
    unique = tuple(dict.fromkeys(indices))
    forms = []
    for u in unique:
        default, *others = [j for j, i in enumerate(indices) if i == u]
        best = min(others, key=lambda j: ss[j], default=default)
        forms.append(best if per > 0 and (ss[default] - ss[best]) / per >= EVIDENCE else default)
    low = min(ss[j] for j in forms)
    per = low / n
    excess = tuple(float((ss[j] - low) / per) if per > 0 else 0.0 for j in forms)
    return Replay(unique, excess, tuple(forms), unique[int(np.argmin(excess))], per)


def info(rp: Replay, names: Sequence[str], of: str) -> ReplayInfo:
    """The replay as ``diagnosis.json`` reports it (``names`` by index; ``of``: "verdict" or "second_effect")."""
    return ReplayInfo(of=of, excess={names[i]: r6(e) for i, e in zip(rp.indices, rp.excess)}, evidence=EVIDENCE,
                      mean_square=r6(rp.quality), decides=rp.decides)
