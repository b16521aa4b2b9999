"""Exam-question statistics: two-group comparisons, ANCOVA, item analysis and power.

``a`` is always the treated group (with the lab reference) and ``b`` the
control, so a negative difference means the lab reference hurt. Each function
returns ``None`` when its statistic is undefined for the data at hand.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
import statsmodels.formula.api as smf
from scipy import stats
from statsmodels.stats.power import TTestIndPower

Interval = tuple[float, float]
POWER = 0.80
ALPHA = 0.05


@dataclass(frozen=True)
class WelchResult:
    diff: float
    t: float
    df: float
    p: float
    ci: Interval


@dataclass(frozen=True)
class AncovaResult:
    n: int
    diff: float
    ci: Interval
    p: float


def welch(a: np.ndarray, b: np.ndarray, level: float = 0.95) -> WelchResult | None:
    """Welch's unequal-variance t-test of mean(a) − mean(b), with its CI."""
    if len(a) < 2 or len(b) < 2 or (np.var(a) == 0 and np.var(b) == 0):
        return None
    result = stats.ttest_ind(a, b, equal_var=False)
    ci = result.confidence_interval(confidence_level=level)
    return WelchResult(
        diff=float(np.mean(a) - np.mean(b)),
        t=float(result.statistic),
        df=float(result.df),
        p=float(result.pvalue),
        ci=(float(ci.low), float(ci.high)),
    )


def mann_whitney(a: np.ndarray, b: np.ndarray) -> tuple[float, float] | None:
    """Two-sided Mann-Whitney U (U of group ``a``, as R's W) and its p-value."""
    if len(a) == 0 or len(b) == 0:
        return None
    result = stats.mannwhitneyu(a, b, alternative="two-sided")
    return float(result.statistic), float(result.pvalue)


def hedges_j(df: float) -> float:
    """Hedges' exact small-sample correction J(df) = Γ(df/2) / (√(df/2) Γ((df−1)/2))."""
    return math.exp(math.lgamma(df / 2) - 0.5 * math.log(df / 2) - math.lgamma((df - 1) / 2))


def hedges_g(a: np.ndarray, b: np.ndarray, level: float = 0.95) -> tuple[float, Interval] | None:
    """Hedges' g (pooled SD, exact J) with a normal-approximation CI.

    SE follows Borenstein et al. (2009): Var(d) = (n1+n2)/(n1 n2) + d²/(2(n1+n2)),
    Var(g) = J² Var(d).
    """
    n1, n2 = len(a), len(b)
    if n1 < 2 or n2 < 2:
        return None
    pooled = math.sqrt(((n1 - 1) * np.var(a, ddof=1) + (n2 - 1) * np.var(b, ddof=1)) / (n1 + n2 - 2))
    if pooled == 0:
        return None
    d = (np.mean(a) - np.mean(b)) / pooled
    j = hedges_j(n1 + n2 - 2)
    se = j * math.sqrt((n1 + n2) / (n1 * n2) + d * d / (2 * (n1 + n2)))
    z = stats.norm.ppf(0.5 + level / 2)
    g = j * d
    return float(g), (float(g - z * se), float(g + z * se))


def ancova(frame: pd.DataFrame, treated: str, control: str, level: float = 0.95) -> AncovaResult | None:
    """OLS ``score ~ C(group) + rest`` (``+ C(problem)`` if several): the adjusted group effect.

    ``frame`` has columns score, group, rest and problem; the effect is treated − control.
    """
    terms = 3 + frame["problem"].nunique() - 1  # intercept, group, rest, problem levels beyond the first
    if frame["group"].nunique() < 2 or len(frame) <= terms or frame["rest"].nunique() < 2:
        return None  # no residual degree of freedom: the report says the adjustment was not possible
    formula = f"score ~ C(group, Treatment(reference={control!r})) + rest"
    if frame["problem"].nunique() > 1:
        formula += " + C(problem)"
    fit = smf.ols(formula, data=frame).fit()
    term = next(name for name in fit.params.index if name.endswith(f"[T.{treated}]"))
    if not np.isfinite(fit.bse[term]) or fit.df_resid < 1:
        return None
    low, high = fit.conf_int(alpha=1 - level).loc[term]
    return AncovaResult(n=int(fit.nobs), diff=float(fit.params[term]), ci=(float(low), float(high)),
                        p=float(fit.pvalues[term]))


def item_rest_r(item: np.ndarray, rest: np.ndarray) -> float | None:
    """Corrected item–total (item–rest) Pearson correlation."""
    if len(item) < 3 or np.std(item) == 0 or np.std(rest) == 0:
        return None
    return float(np.corrcoef(item, rest)[0, 1])


def upper_lower_index(item: np.ndarray, rest: np.ndarray, item_max: float, fraction: float = 0.27) -> float | None:
    """Kelley's upper–lower discrimination index on the rest-of-test score.

    (mean item score of the top 27 % − that of the bottom 27 %) / item max.
    Students are ranked by rest score; students tied at a cut share its last places, each with an equal weight,
    so that the index does not hang on the rows' order (:func:`_group_mean`).
    """
    size = round(fraction * len(item))
    if size < 1 or 2 * size > len(item):
        return None
    item, rest = np.asarray(item, dtype=float), np.asarray(rest, dtype=float)
    return float((_group_mean(item, -rest, size) - _group_mean(item, rest, size)) / item_max)


def _group_mean(item: np.ndarray, rank: np.ndarray, size: int) -> float:
    """Mean item score of the ``size`` students lowest in ``rank``; the students tied at the cut fill its
    remaining places with equal weights."""
    cut = np.sort(rank)[size - 1]
    below, tied = rank < cut, rank == cut
    weight = below + tied * (size - int(below.sum())) / int(tied.sum())
    return float(weight @ item / size)


def minimum_detectable_d(n1: int, n2: int, power: float = POWER, alpha: float = ALPHA) -> float | None:
    """Smallest |d| a two-sided two-sample t-test detects with ``power`` at these sizes."""
    if n1 < 2 or n2 < 2:
        return None
    return float(TTestIndPower().solve_power(nobs1=n1, ratio=n2 / n1, alpha=alpha, power=power))


def n_per_group(d: float, power: float = POWER, alpha: float = ALPHA) -> int | None:
    """Students per group (equal groups) needed to detect |d| with ``power``."""
    if not np.isfinite(d) or abs(d) < 0.01:
        return None
    return math.ceil(TTestIndPower().solve_power(effect_size=abs(d), ratio=1.0, alpha=alpha, power=power))
