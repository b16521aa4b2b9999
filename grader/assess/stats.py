"""Survey statistics: Likert summaries, Cronbach's alpha, Friedman/Kendall's W, Wilcoxon/Holm.

Pure functions on numpy arrays. Missing data are NaN and are dropped (or, for
the within-student tests, define the complete cases); they are never counted
as neutral. Functions return ``None`` where a statistic is undefined rather
than inventing a value.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats
from statsmodels.stats.multitest import multipletests

Interval = tuple[float, float]


@dataclass(frozen=True)
class LikertSummary:
    n: int
    counts: tuple[int, ...]
    pct_disagree: float | None
    pct_neutral: float | None
    pct_agree: float | None
    median: float | None
    q1: float | None
    q3: float | None
    mean: float | None
    sd: float | None
    mean_ci: Interval | None


@dataclass(frozen=True)
class FriedmanResult:
    n: int
    k: int
    chi2: float
    df: int
    p: float
    kendall_w: float


@dataclass(frozen=True)
class PairResult:
    a: str
    b: str
    n: int
    statistic: float | None
    p: float | None
    p_holm: float | None
    mean_diff: float | None


def mean_ci(values: np.ndarray, level: float = 0.95) -> Interval | None:
    """t-based confidence interval of the mean (``None`` if n < 2)."""
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    if x.size < 2:
        return None
    half = stats.t.ppf(0.5 + level / 2, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size)
    return float(x.mean() - half), float(x.mean() + half)


def likert_summary(values: np.ndarray, points: int) -> LikertSummary:
    """n, category counts, % disagree/neutral/agree, median/IQR, mean/SD/CI."""
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    counts = tuple(int(np.sum(x == v)) for v in range(1, points + 1))
    n = int(x.size)
    if n == 0:
        return LikertSummary(0, counts, None, None, None, None, None, None, None, None, None)
    mid = (points + 1) / 2
    q1, median, q3 = (float(q) for q in np.percentile(x, [25, 50, 75]))
    return LikertSummary(
        n=n,
        counts=counts,
        pct_disagree=100.0 * np.sum(x < mid) / n,
        pct_neutral=100.0 * np.sum(x == mid) / n,
        pct_agree=100.0 * np.sum(x > mid) / n,
        median=median,
        q1=q1,
        q3=q3,
        mean=float(x.mean()),
        sd=float(x.std(ddof=1)) if n > 1 else None,
        mean_ci=mean_ci(x),
    )


def complete_rows(matrix: np.ndarray) -> np.ndarray:
    """Rows of a respondents × columns matrix with no missing value."""
    m = np.asarray(matrix, dtype=float)
    return m[~np.isnan(m).any(axis=1)]


def cronbach_alpha(matrix: np.ndarray) -> float | None:
    """Cronbach's alpha of a complete respondents × items matrix."""
    m = np.asarray(matrix, dtype=float)
    n, k = m.shape
    if n < 2 or k < 2:
        return None
    total_var = m.sum(axis=1).var(ddof=1)
    if total_var == 0:
        return None
    return float(k / (k - 1) * (1 - m.var(axis=0, ddof=1).sum() / total_var))


def feldt_ci(alpha: float, n: int, k: int, level: float = 0.95) -> Interval | None:
    """Feldt, Woodruff & Salih (1987) interval for alpha: F(n-1, (n-1)(k-1))."""
    if n < 3 or k < 2:
        return None
    df1, df2 = n - 1, (n - 1) * (k - 1)
    tail = (1 - level) / 2
    low = 1 - (1 - alpha) * stats.f.ppf(1 - tail, df1, df2)
    high = 1 - (1 - alpha) * stats.f.ppf(tail, df1, df2)
    return float(low), float(high)


def kendall_w(chi2: float, n: int, k: int) -> float:
    """Kendall's coefficient of concordance from the (tie-corrected) Friedman chi²."""
    return chi2 / (n * (k - 1))


def friedman(matrix: np.ndarray) -> FriedmanResult | None:
    """Friedman test over the complete rows of respondents × conditions.

    ``None`` when there are fewer than 3 conditions or 2 complete rows, or when
    every respondent gave the same rating everywhere (the statistic is undefined).
    """
    m = complete_rows(matrix)
    n, k = m.shape
    if k < 3 or n < 2:
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        result = stats.friedmanchisquare(*m.T)
    chi2, p = float(result.statistic), float(result.pvalue)
    if not np.isfinite(chi2):
        return None
    return FriedmanResult(n=n, k=k, chi2=chi2, df=k - 1, p=p, kendall_w=kendall_w(chi2, n, k))


def wilcoxon_pair(
    a: np.ndarray, b: np.ndarray, alternative: str = "two-sided"
) -> tuple[int, float | None, float | None, float | None]:
    """Wilcoxon signed-rank test of a − b on pairwise-complete cases.

    Returns ``(n, V, p, mean_diff)`` with V the sum of the ranks of the positive
    differences, as R reports it. Zero differences are dropped (R's default);
    with ties the normal approximation is continuity corrected, as in R. If every
    difference is zero, p is 1: there is no evidence of a difference.
    """
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    keep = ~(np.isnan(x) | np.isnan(y))
    diff = x[keep] - y[keep]
    n = int(diff.size)
    if n == 0:
        return 0, None, None, None
    if np.all(diff == 0):
        return n, 0.0, 1.0, 0.0
    nonzero = diff[diff != 0]
    v = float(stats.rankdata(np.abs(nonzero))[nonzero > 0].sum())
    result = stats.wilcoxon(x[keep], y[keep], correction=True, alternative=alternative)
    return n, v, float(result.pvalue), float(diff.mean())


def holm(pvalues: Sequence[float | None]) -> list[float | None]:
    """Holm-adjusted p-values; ``None`` entries stay ``None`` and are not counted."""
    present = [p for p in pvalues if p is not None]
    if not present:
        return [None] * len(pvalues)
    adjusted = iter(multipletests(present, method="holm")[1])
    return [None if p is None else float(next(adjusted)) for p in pvalues]


def pairwise_wilcoxon(columns: dict[str, np.ndarray]) -> list[PairResult]:
    """All pairs of conditions, Wilcoxon signed-rank, Holm-corrected within the family."""
    raw = [(a, b, *wilcoxon_pair(columns[a], columns[b])) for a, b in itertools.combinations(columns, 2)]
    adjusted = holm([r[4] for r in raw])
    return [
        PairResult(a=a, b=b, n=n, statistic=s, p=p, p_holm=ph, mean_diff=d)
        for (a, b, n, s, p, d), ph in zip(raw, adjusted, strict=True)
    ]
