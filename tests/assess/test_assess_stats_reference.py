"""Survey statistics against published reference results."""

from __future__ import annotations

import numpy as np
import pytest

from grader.assess import stats

# R: ?friedman.test, Hollander & Wolfe (1973) p. 140ff: 22 players × 3 ways of rounding first base.
ROUNDING_TIMES = np.array([
    [5.40, 5.50, 5.55], [5.85, 5.70, 5.75], [5.20, 5.60, 5.50], [5.55, 5.50, 5.40],
    [5.90, 5.85, 5.70], [5.45, 5.55, 5.60], [5.40, 5.40, 5.35], [5.45, 5.50, 5.35],
    [5.25, 5.15, 5.00], [5.85, 5.80, 5.70], [5.25, 5.20, 5.10], [5.65, 5.55, 5.45],
    [5.60, 5.35, 5.45], [5.05, 5.00, 4.95], [5.50, 5.50, 5.40], [5.45, 5.55, 5.50],
    [5.55, 5.55, 5.35], [5.45, 5.50, 5.55], [5.50, 5.45, 5.25], [5.65, 5.60, 5.40],
    [5.70, 5.65, 5.55], [6.30, 6.30, 6.25],
])  # columns: Round Out, Narrow Angle, Wide Angle

# R: ?wilcox.test, Hollander & Wolfe (1973) p. 29f: Hamilton depression scale before (x) and after (y).
DEPRESSION_X = np.array([1.83, 0.50, 1.62, 2.48, 1.68, 1.88, 1.55, 3.06, 1.30])
DEPRESSION_Y = np.array([0.878, 0.647, 0.598, 2.05, 1.06, 1.29, 1.06, 3.14, 1.29])

# R: datasets::sleep, extra sleep under drug 1 and drug 2 (same 10 patients).
SLEEP_1 = np.array([0.7, -1.6, -0.2, -1.2, -0.1, 3.4, 3.7, 0.8, 0.0, 2.0])
SLEEP_2 = np.array([1.9, 0.8, 1.1, 0.1, -0.1, 4.4, 5.5, 1.6, 4.6, 3.4])


def test_friedman_matches_r_rounding_times() -> None:
    # friedman.test(RoundingTimes): Friedman chi-squared = 11.143, df = 2, p-value = 0.003805
    result = stats.friedman(ROUNDING_TIMES)
    assert result is not None
    assert result.chi2 == pytest.approx(11.143, abs=5e-4)
    assert result.df == 2
    assert result.p == pytest.approx(0.003805, abs=5e-7)
    assert result.n == 22


def test_kendall_w_from_friedman_rounding_times() -> None:
    # rstatix::friedman_effsize / DescTools::KendallW: W = chi2 / (n (k - 1)) = 11.143 / 44
    result = stats.friedman(ROUNDING_TIMES)
    assert result is not None
    assert result.kendall_w == pytest.approx(11.142857 / 44, abs=1e-6)


def test_kendall_w_matches_nag_g08daf_example_with_ties() -> None:
    # NAG Fortran Library G08DAF example: 3 comparisons (raters) rank 10 objects, with ties;
    # published result: Kendall's coefficient = 0.828, significance = 0.008.
    ranks = np.array([
        [1.0, 4.5, 2.0, 4.5, 3.0, 7.5, 6.0, 9.0, 7.5, 10.0],
        [2.5, 1.0, 2.5, 4.5, 4.5, 8.0, 9.0, 6.5, 10.0, 6.5],
        [2.0, 1.0, 4.5, 4.5, 4.5, 4.5, 8.0, 8.0, 8.0, 10.0],
    ])
    result = stats.friedman(ranks)  # raters are the blocks, objects the conditions
    assert result is not None
    assert round(result.kendall_w, 3) == 0.828
    assert round(result.p, 3) == 0.008


def test_wilcoxon_matches_r_depression_example() -> None:
    # wilcox.test(x, y, paired = TRUE, alternative = "greater"): V = 40, p-value = 0.01953
    n, v, p, _ = stats.wilcoxon_pair(DEPRESSION_X, DEPRESSION_Y, alternative="greater")
    assert (n, v) == (9, 40.0)
    assert p == pytest.approx(0.01953, abs=5e-6)


def test_wilcoxon_uses_pairwise_complete_cases() -> None:
    x = np.append(DEPRESSION_X, [np.nan, 2.0])
    y = np.append(DEPRESSION_Y, [1.0, np.nan])
    n, v, _, _ = stats.wilcoxon_pair(x, y, alternative="greater")
    assert (n, v) == (9, 40.0)


def test_wilcoxon_all_zero_differences_is_no_evidence() -> None:
    n, v, p, diff = stats.wilcoxon_pair(np.array([3.0, 4, 5]), np.array([3.0, 4, 5]))
    assert (n, v, p, diff) == (3, 0.0, 1.0, 0.0)


def test_holm_matches_r_p_adjust() -> None:
    # p.adjust(c(0.01, 0.02, 0.03, 0.04, 0.05), "holm") = 0.05 0.08 0.09 0.09 0.09 (Holm 1979 step-down)
    assert stats.holm([0.01, 0.02, 0.03, 0.04, 0.05]) == pytest.approx([0.05, 0.08, 0.09, 0.09, 0.09])
    assert stats.holm([0.01, None, 0.04]) == pytest.approx([0.02, None, 0.04])


def test_mean_ci_matches_r_paired_t_test_on_sleep() -> None:
    # t.test(extra ~ group, data = sleep, paired = TRUE): 95 percent CI -2.4598858 -0.7001142
    low, high = stats.mean_ci(SLEEP_1 - SLEEP_2)
    assert low == pytest.approx(-2.4598858, abs=1e-7)
    assert high == pytest.approx(-0.7001142, abs=1e-7)


def test_cronbach_alpha_matches_published_worked_example() -> None:
    # thinkdeeply.cc "Survey reliability": 10 respondents × 4 Likert items, alpha = 0.674
    # (by hand from the covariance matrix, and R's cronbach(): "alpha: 0.674").
    data = np.array([
        [3, 3, 3, 3], [3, 3, 4, 3], [3, 3, 3, 1], [5, 4, 4, 5], [2, 1, 4, 4],
        [4, 4, 4, 5], [3, 2, 3, 3], [3, 4, 3, 3], [4, 2, 2, 3], [3, 3, 2, 3],
    ], dtype=float)
    assert round(stats.cronbach_alpha(data), 3) == 0.674


def test_cronbach_alpha_equals_covariance_form() -> None:
    # alpha = N c̄ / (v̄ + (N-1) c̄), the same example's second route (c̄ = 0.309, v̄ = 0.908).
    rng = np.random.default_rng(1)
    data = rng.integers(1, 6, size=(30, 5)).astype(float)
    cov = np.cov(data, rowvar=False)
    k = cov.shape[0]
    c_bar = (cov.sum() - np.trace(cov)) / (k * (k - 1))
    v_bar = np.trace(cov) / k
    assert stats.cronbach_alpha(data) == pytest.approx(k * c_bar / (v_bar + (k - 1) * c_bar))


def test_feldt_interval_matches_feldt_woodruff_salih_1987() -> None:
    # Feldt, Woodruff & Salih (1987) p. 95: alpha = .790, n = 41, k = 26, 90 % interval;
    # cocron::cronbach.alpha.CI gives .705 and .862 (the article's .704/.861 used 2-digit F tables).
    low, high = stats.feldt_ci(0.790, 41, 26, level=0.90)
    assert (round(low, 3), round(high, 3)) == (0.705, 0.862)


def test_likert_summary_of_a_small_item() -> None:
    values = np.array([1, 2, 3, 3, 4, 5, 5, 5, np.nan, np.nan])
    s = stats.likert_summary(values, points=5)
    assert s.n == 8
    assert s.counts == (1, 1, 2, 1, 3)
    assert (s.pct_disagree, s.pct_neutral, s.pct_agree) == pytest.approx((25.0, 25.0, 50.0))
    assert s.median == 3.5
    assert (s.q1, s.q3) == (2.75, 5.0)  # R's quantile type 7
    assert s.mean == pytest.approx(3.5)


def test_missing_values_are_never_neutral() -> None:
    s = stats.likert_summary(np.array([np.nan, np.nan, 5.0]), points=5)
    assert (s.n, s.pct_neutral, s.pct_agree) == (1, 0.0, 100.0)


def test_friedman_needs_three_conditions_and_complete_rows() -> None:
    assert stats.friedman(np.array([[1.0, 2.0], [2.0, 3.0]])) is None
    m = np.array([[1.0, 2, 3], [np.nan, 2, 3], [3.0, 2, 1], [1.0, 3, 2]])
    result = stats.friedman(m)
    assert result is not None and result.n == 3


def test_friedman_all_ties_is_undefined() -> None:
    assert stats.friedman(np.full((5, 4), 3.0)) is None
