"""Ranking the candidates and the verdict.

Score = geometric mean over runs of the held-out NRMSE² (robust to the one run the others
cannot predict, see :func:`grader.gap.crossval.typical`), times (1 + PENALTY·k) for k extra
parameters (an effect without free parameters counts one: choosing it is a degree of
freedom). The best-scoring effect is the verdict only if it explains *clearly more than
noise*, i.e. its evidence E > 1, where E is the smaller of

* its held-out gain over ``none`` (1 − its score's ratio to ``none``'s, both unpenalised), in
  units of REL_GAIN, and
* its all-runs fit's mean-square gain over ``none``, in units of NOISE_GAIN × the noise
  floor's (an effect the data cannot see fits no better than ``none``, while its held-out
  score still varies from fold to fold);

otherwise the verdict is ``none``. Margin: ln(score of the runner-up / score of the
verdict) for an effect; for ``none``, ln(1/E) of the best effect (how far it falls short).
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
REL_GAIN = 0.10
NOISE_GAIN = 0.5
TIE = 0.05
TIE_FIT = 0.25
BOOTSTRAP = 400
VISIBLE = 0.1  # fitted strength (fraction of the realistic range's top) that would show
MAX_MARGIN = 10.0


@dataclass(frozen=True)
class Scored:
    """A candidate's held-out and all-runs-fit NRMSE per run, its extra parameters and fitted strength."""

    effect: str
    heldout: Array
    fit: Array
    k_extra: int
    strength: float = 0.0


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


def evidence(none: Scored, eff: Scored, noise_nrmse: Array, w: Array, gain: float = NOISE_GAIN) -> float:
    """E of ``eff`` against ``none`` (see module docstring; the fit's gain in units of ``gain`` × the floor's
    mean square); > 1 means clearly more than noise."""
    held = (1.0 - _held(eff, w) / _held(none, w)) / REL_GAIN
    fit = (_ms(none.fit, w) - _ms(eff.fit, w)) / (gain * _ms(noise_nrmse, w))
    return min(held, fit)


def decide(cands: Sequence[Scored], noise_nrmse: Array, weights: Array | None = None, *,
           reference: int | None = None, gain: float = NOISE_GAIN) -> tuple[int, int, float]:
    """(verdict, best effect, its evidence): the best-scoring effect if E > 1 against the reference
    (default ``none``; for a second effect, the first alone, with ``noise_nrmse`` the floor it leaves and
    a larger ``gain``), else the reference."""
    w = np.ones(noise_nrmse.size) if weights is None else weights
    s = scores(cands, w)
    i_none = next(i for i, c in enumerate(cands) if c.effect == NONE) if reference is None else reference
    effects = [i for i in range(len(cands)) if i != i_none]
    if not effects:
        return i_none, i_none, 0.0
    best = min(effects, key=lambda i: s[i])
    e = evidence(cands[i_none], cands[best], noise_nrmse, w, gain)
    return (best if e > 1.0 else i_none), best, e


def _ties(cands: Sequence[Scored], s: Array, verdict: int, noise_nrmse: Array, w: Array | None = None) -> list[int]:
    w = np.ones(noise_nrmse.size) if w is None else w
    if cands[verdict].effect != NONE:
        v, floor = cands[verdict], _ms(noise_nrmse, w)
        return [i for i, c in enumerate(cands) if i != verdict and c.effect != NONE
                and (np.log(s[i] / s[verdict]) < TIE or _ms(c.fit, w) - _ms(v.fit, w) < TIE_FIT * floor)]
    none, floor = cands[verdict], NOISE_GAIN * _ms(noise_nrmse, w)
    return [i for i, c in enumerate(cands) if i != verdict and c.strength >= VISIBLE
            and abs(_ms(none.fit, w) - _ms(c.fit, w)) < floor]


def rank(cands: Sequence[Scored], noise_nrmse: Array, *, seed: int = 0) -> Ranking:
    """Order (verdict first, then by score), margin, run-bootstrap confidence and ties."""
    s = scores(cands)
    verdict, _, e = decide(cands, noise_nrmse)
    rest = [int(i) for i in np.argsort(s, kind="stable") if i != verdict]
    runner = rest[0] if rest else None
    if cands[verdict].effect == NONE:
        margin = float(-np.log(max(e, np.exp(-MAX_MARGIN))))
    else:
        margin = float(np.log(s[runner] / s[verdict])) if runner is not None else MAX_MARGIN
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
    rows = np.arange(BOOTSTRAP)
    best = np.argmin(np.where(np.arange(len(cands)) == i_none, np.inf, s), axis=1)
    e = np.minimum((1.0 - held[rows, best] / held[:, i_none]) / REL_GAIN,
                   (fit[:, i_none] - fit[rows, best]) / (NOISE_GAIN * floor))
    same = np.where(e > 1.0, best, i_none) == verdict
    if cands[verdict].effect == NONE:
        return float(np.sum(same)) / BOOTSTRAP
    others = np.array([i != verdict and c.effect != NONE for i, c in enumerate(cands)])
    tied = (np.log(s / s[:, [verdict]]) < TIE) | (fit - fit[:, [verdict]] < TIE_FIT * floor[:, None])
    return float(np.sum(same & ~np.any(tied & others, axis=1))) / BOOTSTRAP
