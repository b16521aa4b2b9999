"""Ranking the candidates and the verdict.

Score = geometric mean over runs of the held-out NRMSE² (robust to the one run the others
cannot predict, see :func:`grader.gap.crossval.typical`), times (1 + PENALTY·k) for k extra
parameters (an effect without free parameters counts one: choosing it is a degree of
freedom). An effect can be the verdict only if it explains *clearly more than noise*, i.e. its
evidence E > 1 (below); among those, the verdict is the best-scoring one or, among the effects
scoring within CLOSE of it, the one that fits all runs best (the held-out score carries the folds'
refitting noise, the fit is the likelihood of models of one size). E is the smaller of

* its held-out gain over ``none`` (1 − its score's ratio to ``none``'s, both unpenalised), in
  units of REL_GAIN, and
* its all-runs fit's mean-square gain over ``none``, in units of NOISE_GAIN × the noise
  floor's (an effect the data cannot see fits no better than ``none``, while its held-out
  score still varies from fold to fold);

with no such effect the verdict is ``none``. Margin: ln(score of the runner-up / score of the
verdict) for an effect (0 when a runner-up scores better); for ``none``, ln(1/E) of the effect
that came closest (how far it falls short).
Candidates the data cannot tell apart from the verdict: for an effect, other effects
scoring within TIE of it or fitting all runs as well as it (within TIE_FIT of the noise
floor's mean square: e.g. a delay and a spool lag near the noise); for ``none``, effects
fitted at a visible strength that fit as well as ``none`` (e.g. viscous friction against a
larger Kce). The confidence is the share of bootstrap resamples of the runs (fixed seed)
that give the same verdict, and for an effect, no candidate tied with it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from grader.gap.candidates import NONE
from grader.gap.crossval import FLOOR, typical

Array = NDArray[np.float64]
PENALTY = 0.02
#: Units of the evidence (module docstring): a held-out gain of REL_GAIN and a fit gain of NOISE_GAIN × the noise
#: floor's mean square. On 50 benchmark datasets with no effect the best effect's fit gain stayed below 0.06 of the
#: floor, while weak real effects (a 0.5 ms delay under 0.8 mil of noise) gained 0.3.
REL_GAIN = 0.02
NOISE_GAIN = 0.2
TIE = 0.05
TIE_FIT = 0.25
BOOTSTRAP = 400
VISIBLE = 0.1  # fitted strength (fraction of the realistic range's top) that would show
#: An effect fitted below this strength (fraction of its realistic range's top) does not act: it is ``none`` at
#: another optimum of the linear parameters (a Coulomb level of 0 lbf), and it is neither the verdict nor a lookalike.
ACTING = 1e-3
MAX_MARGIN = 10.0
#: Effects whose held-out scores lie within this log ratio of the best are ranked by their all-runs fit: the
#: fit is the likelihood of models of equal size, while the held-out score adds the folds' refitting noise
#: (a delay and a spool lag of a millisecond).
CLOSE = 0.2


@dataclass(frozen=True)
class Scored:
    """A candidate's held-out and all-runs-fit NRMSE per run, its extra parameters and fitted strength."""

    effect: str
    heldout: Array
    fit: Array
    k_extra: int
    strength: float  # fitted strength of the (last added) effect, a fraction of its realistic range's top

    @property
    def fit_ms(self) -> float:
        """Mean square over runs of the all-runs fit's NRMSE (runs weighted alike)."""
        return float(np.mean(self.fit**2))

    @property
    def acts(self) -> bool:
        """Whether the effect is fitted at a strength that acts (:data:`ACTING`)."""
        return self.strength >= ACTING


@dataclass(frozen=True)
class Ranking:
    order: list[int]
    scores: Array
    verdict: int
    runner_up: int | None
    margin: float
    confidence: float
    ties: list[int]


def _ms(x: Array, w: Array) -> float:
    return float(np.average(x**2, weights=w))


def _held(c: Scored, w: Array) -> float:
    """Typical held-out NRMSE², unpenalised."""
    return typical(c.heldout**2, w)


def scores(cands: Sequence[Scored], weights: Array | None = None) -> Array:
    """Penalised typical held-out NRMSE² of each candidate (runs weighted by ``weights``)."""
    w = np.ones(cands[0].heldout.size) if weights is None else weights
    held = np.array([_held(c, w) for c in cands])
    return held * (1.0 + PENALTY * np.array([c.k_extra for c in cands]))


def evidence(none: Scored, eff: Scored, noise_nrmse: Array, w: Array, gain: float = NOISE_GAIN,
             rel_gain: float = REL_GAIN) -> float:
    """E of ``eff`` against ``none`` (see module docstring; the held-out gain in units of ``rel_gain``, the fit's
    in units of ``gain`` × the floor's mean square); > 1 means clearly more than noise."""
    held = (1.0 - _held(eff, w) / _held(none, w)) / rel_gain
    return min(held, fit_gain(none.fit, eff.fit, noise_nrmse, w, gain))


def fit_gain(reference: Array, fit: Array, noise_nrmse: Array, w: Array, gain: float = NOISE_GAIN) -> float:
    """The all-runs fit's half of E: how far the per-run NRMSE ``fit`` lowers the mean square of ``reference``'s, in
    units of ``gain`` × the floor's mean square (E > 1 needs this above 1 too)."""
    return (_ms(reference, w) - _ms(fit, w)) / (gain * _ms(noise_nrmse, w))


def decide(cands: Sequence[Scored], noise_nrmse: Array, weights: Array | None = None, *,
           reference: int | None = None, gain: float = NOISE_GAIN, rel_gain: float = REL_GAIN) -> tuple[int, int, float]:
    """(verdict, best effect, its evidence): among the effects with E > 1 against the reference (default
    ``none``; for a second effect, the first alone, with ``noise_nrmse`` the floor it leaves and a larger
    ``gain``), the best (module docstring); without one, the reference, and the effect that came closest.
    An effect whose fold refits happen to predict the left-out runs better while it fits all runs no better
    than the reference is no candidate for the verdict, nor is one fitted at no strength (:data:`ACTING`)."""
    w = np.ones(noise_nrmse.size) if weights is None else weights
    s = scores(cands, w)
    i_none, e = _evidences(cands, noise_nrmse, w, reference, gain, rel_gain)
    if not e:  # no effect, or every one fitted at no strength: each is the reference itself
        return i_none, i_none, 0.0
    ok = [i for i in e if e[i] > 1.0]
    if not ok:
        closest = max(e, key=lambda i: e[i])
        return i_none, closest, e[closest]
    top = min(ok, key=lambda i: s[i])
    best = min((i for i in ok if np.log(s[i] / s[top]) < CLOSE), key=lambda i: _ms(cands[i].fit, w))
    return best, best, e[best]


def _evidences(cands: Sequence[Scored], noise_nrmse: Array, w: Array, reference: int | None, gain: float,
               rel_gain: float) -> tuple[int, dict[int, float]]:
    """The reference's index (default ``none``'s) and E of each effect that acts against it."""
    i_none = next(i for i, c in enumerate(cands) if c.effect == NONE) if reference is None else reference
    acting = [i for i in range(len(cands)) if i != i_none and cands[i].acts]
    return i_none, {i: evidence(cands[i_none], cands[i], noise_nrmse, w, gain, rel_gain) for i in acting}


def explaining(cands: Sequence[Scored], noise_nrmse: Array, *, reference: int | None = None, gain: float = NOISE_GAIN,
               rel_gain: float = REL_GAIN) -> list[int]:
    """The effects that explain clearly more than the reference (E > 1, in :func:`decide`'s units): those
    :func:`decide` chooses among."""
    _, e = _evidences(cands, noise_nrmse, np.ones(noise_nrmse.size), reference, gain, rel_gain)
    return [i for i in e if e[i] > 1.0]


def lookalikes(cands: Sequence[Scored], noise_nrmse: Array, pick: int, reference: int, *, gain: float = NOISE_GAIN,
               rel_gain: float = REL_GAIN) -> list[int]:
    """The effects the data cannot tell apart from ``pick``, an effect :func:`decide` chose over ``reference``: each
    also explains clearly more than the reference (E > 1, in the same units) and scores within TIE of ``pick`` or fits
    all runs as well (within TIE_FIT of the floor's mean square)."""
    w = np.ones(noise_nrmse.size)
    s, floor, best = scores(cands, w), _ms(noise_nrmse, w), cands[pick]
    return [i for i, c in enumerate(cands) if i not in (pick, reference) and c.acts
            and evidence(cands[reference], c, noise_nrmse, w, gain, rel_gain) > 1.0
            and (np.log(s[i] / s[pick]) < TIE or _ms(c.fit, w) - _ms(best.fit, w) < TIE_FIT * floor)]


def _ties(cands: Sequence[Scored], s: Array, verdict: int, noise_nrmse: Array, w: Array | None = None) -> list[int]:
    w = np.ones(noise_nrmse.size) if w is None else w
    if cands[verdict].effect != NONE:
        v, floor = cands[verdict], _ms(noise_nrmse, w)
        return [i for i, c in enumerate(cands) if i != verdict and c.effect != NONE and c.acts
                and (np.log(s[i] / s[verdict]) < TIE or _ms(c.fit, w) - _ms(v.fit, w) < TIE_FIT * floor)]
    none, floor = cands[verdict], NOISE_GAIN * _ms(noise_nrmse, w)
    return [i for i, c in enumerate(cands) if i != verdict and c.strength >= VISIBLE
            and abs(_ms(none.fit, w) - _ms(c.fit, w)) < floor]


def rank(cands: Sequence[Scored], noise_nrmse: Array, *, seed: int = 0, verdict: int | None = None) -> Ranking:
    """Order (verdict first, then by score), margin, run-bootstrap confidence and ties; the runner-up is the best
    scoring of the others that is ``none`` or acts (:data:`ACTING`). A given ``verdict`` is kept (a verdict ranked
    again after another candidate's fit was replaced)."""
    s = scores(cands)
    decided, _, e = decide(cands, noise_nrmse)
    verdict = decided if verdict is None else verdict
    rest = [int(i) for i in np.argsort(s, kind="stable") if i != verdict]
    runner = next((i for i in rest if cands[i].effect == NONE or cands[i].acts), None)
    if cands[verdict].effect == NONE:
        margin = max(float(-np.log(max(e, np.exp(-MAX_MARGIN)))), 0.0)  # 0: a kept none that an effect beats
    else:
        margin = max(float(np.log(s[runner] / s[verdict])), 0.0) if runner is not None else MAX_MARGIN
    return Ranking([verdict, *rest], s, verdict, runner, min(margin, MAX_MARGIN),
                   _confidence(cands, noise_nrmse, verdict, seed), _ties(cands, s, verdict, noise_nrmse))


def _wmean(w: Array, x: Array) -> Array:
    """Weighted means of the rows of ``x`` (candidates × runs) under each weight row of ``w``
    (resamples × runs): (resamples × candidates), as :func:`numpy.average` sums (no BLAS)."""
    return (w[:, None, :] * x[None, :, :]).sum(axis=2) / w.sum(axis=1)[:, None]


def _confidence(cands: Sequence[Scored], noise_nrmse: Array, verdict: int, seed: int) -> float:
    """Share of run-bootstrap resamples giving the same verdict (an effect: and no candidate tied with it);
    :func:`decide` and :func:`_ties` on every resample at once."""
    rng = np.random.default_rng(seed)
    n = noise_nrmse.size
    w = np.stack([np.bincount(rng.integers(0, n, n), minlength=n) for _ in range(BOOTSTRAP)]).astype(float)
    held = np.exp(_wmean(w, np.log(np.maximum(np.array([c.heldout**2 for c in cands]), FLOOR))))
    s = held * (1.0 + PENALTY * np.array([c.k_extra for c in cands]))
    fit = _wmean(w, np.array([c.fit**2 for c in cands]))
    floor = _wmean(w, (noise_nrmse**2)[None, :])[:, 0]
    i_none = next(i for i, c in enumerate(cands) if c.effect == NONE)
    if len(cands) < 2:
        return 1.0
    is_none = np.arange(len(cands)) == i_none
    e = np.minimum((1.0 - held / held[:, [i_none]]) / REL_GAIN, (fit[:, [i_none]] - fit) / (NOISE_GAIN * floor[:, None]))
    ok = (e > 1.0) & ~is_none & np.array([c.acts for c in cands])
    top = np.min(np.where(ok, s, np.inf), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        close = ok & (np.log(s / top[:, None]) < CLOSE)
    best = np.argmin(np.where(close, fit, np.inf), axis=1)
    same = np.where(ok.any(axis=1), best, i_none) == verdict
    if cands[verdict].effect == NONE:
        return float(np.sum(same)) / BOOTSTRAP
    others = np.array([i != verdict and c.effect != NONE and c.acts for i, c in enumerate(cands)])
    tied = (np.log(s / s[:, [verdict]]) < TIE) | (fit - fit[:, [verdict]] < TIE_FIT * floor[:, None])
    return float(np.sum(same & ~np.any(tied & others, axis=1))) / BOOTSTRAP
