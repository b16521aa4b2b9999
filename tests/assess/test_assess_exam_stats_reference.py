"""Exam statistics against published reference results."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from grader.assess import exam_stats as es

SLEEP_1 = np.array([0.7, -1.6, -0.2, -1.2, -0.1, 3.4, 3.7, 0.8, 0.0, 2.0])
SLEEP_2 = np.array([1.9, 0.8, 1.1, 0.1, -0.1, 4.4, 5.5, 1.6, 4.6, 3.4])

# R: datasets::mtcars (mpg, am, wt).
MPG = [21, 21, 22.8, 21.4, 18.7, 18.1, 14.3, 24.4, 22.8, 19.2, 17.8, 16.4, 17.3, 15.2, 10.4, 10.4,
       14.7, 32.4, 30.4, 33.9, 21.5, 15.5, 15.2, 13.3, 19.2, 27.3, 26, 30.4, 15.8, 19.7, 15, 21.4]
AM = [1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1]
WT = [2.62, 2.875, 2.32, 3.215, 3.44, 3.46, 3.57, 3.19, 3.15, 3.44, 3.44, 4.07, 3.73, 3.78, 5.25, 5.424,
      5.345, 2.2, 1.615, 1.835, 2.465, 3.52, 3.435, 3.84, 3.845, 1.935, 2.14, 1.513, 3.17, 2.77, 3.57, 2.78]


def _with_moments(mean: float, sd: float, n: int) -> np.ndarray:
    """A sample with exactly this mean and SD (n - 1 denominator)."""
    z = np.linspace(-1, 1, n)
    z = (z - z.mean()) / z.std(ddof=1)
    return mean + sd * z


def test_welch_matches_r_sleep() -> None:
    # t.test(extra ~ group, data = sleep): t = -1.8608, df = 17.776, p-value = 0.07939,
    # 95 percent confidence interval: -3.3654832  0.2054832
    result = es.welch(SLEEP_1, SLEEP_2)
    assert result is not None
    assert result.t == pytest.approx(-1.8608, abs=5e-5)
    assert result.df == pytest.approx(17.776, abs=5e-4)
    assert result.p == pytest.approx(0.07939, abs=5e-6)
    assert result.ci == pytest.approx((-3.3654832, 0.2054832), abs=1e-7)
    assert result.diff == pytest.approx(-1.58)


def test_mann_whitney_matches_r_permeability_example() -> None:
    # ?wilcox.test, Hollander & Wolfe (1973) p. 69f: wilcox.test(x, y, alternative = "g"):
    # W = 35, p-value = 0.1272. The exact null distribution is symmetric, so two-sided p = 2 × 0.1272.
    x = np.array([0.80, 0.83, 1.89, 1.04, 1.45, 1.38, 1.91, 1.64, 0.73, 1.46])
    y = np.array([1.15, 0.88, 0.90, 0.74, 1.21])
    u, p = es.mann_whitney(x, y)
    assert u == 35.0
    assert p == pytest.approx(2 * 0.1272, abs=2e-4)


def test_hedges_g_matches_borenstein_worked_example() -> None:
    # Borenstein, Hedges, Higgins & Rothstein (2009), Introduction to Meta-Analysis, ch. 4:
    # means 103 vs 100, SDs 5.5 and 4.5, n = 50 each: d = 0.5970, J = 0.9923, g = 0.5924, SE(g) = 0.2028.
    treated, control = _with_moments(103, 5.5, 50), _with_moments(100, 4.5, 50)
    g, (low, high) = es.hedges_g(treated, control)
    assert round(g, 4) == 0.5924
    assert round(es.hedges_j(98), 4) == 0.9923
    se = (high - low) / (2 * 1.959963984540054)
    assert round(se, 4) == 0.2028


def test_hedges_g_matches_reproducer_calculate_hg() -> None:
    # R reproducer::calculateHg(10, 15, 20, 20, 2, 2): Hg = 2.5, HgAdjusted = 2.450276 (exact J).
    g, _ = es.hedges_g(_with_moments(15, 2, 20), _with_moments(10, 2, 20))
    assert g == pytest.approx(2.450276, abs=1e-6)


def test_ancova_matches_r_lm_on_mtcars() -> None:
    # summary(lm(mpg ~ am + wt, data = mtcars)): amManual -0.02362, SE 1.54565, t -0.015, p 0.988
    frame = pd.DataFrame({
        "score": MPG,
        "group": ["manual" if a else "automatic" for a in AM],
        "rest": WT,
        "problem": "mtcars",
    })
    result = es.ancova(frame, treated="manual", control="automatic")
    assert result is not None
    assert result.diff == pytest.approx(-0.02362, abs=5e-6)
    assert round(result.p, 3) == 0.988
    half_width = (result.ci[1] - result.ci[0]) / 2
    assert half_width == pytest.approx(1.54565 * 2.045229642132703, abs=1e-4)  # SE × t(0.975, 29)


def test_power_matches_cohen_tables() -> None:
    # Cohen (1988) Table 2.4.1, two-tailed α = .05, power .80: n = 64 per group for d = .5, 26 for d = .8.
    assert es.n_per_group(0.5) == 64
    assert es.n_per_group(0.8) == 26
    assert es.minimum_detectable_d(64, 64) == pytest.approx(0.5, abs=0.005)


def test_power_is_undefined_for_no_effect() -> None:
    assert es.n_per_group(0.0) is None
    assert es.minimum_detectable_d(1, 10) is None


def test_item_rest_correlation_and_upper_lower_index_by_hand() -> None:
    # 10 students; top and bottom 27 % (= 3 students each) by rest score.
    item = np.array([0, 1, 1, 2, 2, 3, 3, 4, 4, 4], dtype=float)
    rest = np.arange(10, dtype=float)
    # bottom 3 items: 0, 1, 1 (mean 2/3); top 3: 4, 4, 4 (mean 4); D = (4 - 2/3) / 4
    assert es.upper_lower_index(item, rest, item_max=4) == pytest.approx((4 - 2 / 3) / 4)
    assert es.item_rest_r(item, rest) == pytest.approx(np.corrcoef(item, rest)[0, 1])
    assert es.item_rest_r(np.ones(5), np.arange(5.0)) is None


def test_upper_lower_index_does_not_hang_on_row_order_at_a_tied_cut() -> None:
    """Rest scores tied at the 27 % cut: the tied students share its last places with equal weights, so every order
    of the same rows gives the same index (file order broke the tie, and a real exam's index moved from 0.225 to
    0.253 with its rows reversed). By hand: bottom 3 of 10 = rest 0 (item 0) and two of the three tied at rest 1
    (items 1, 2, 4: mean 7/3 each, weight 2/3); top 3 = rest 8, 8, 9 (items 4, 3, 4)."""
    item = np.array([0, 1, 2, 4, 2, 3, 3, 4, 3, 4], dtype=float)
    rest = np.array([0, 1, 1, 1, 4, 5, 6, 7, 8, 9], dtype=float)
    rest[7] = 8.0
    low = (0 + (1 + 2 + 4) * 2 / 3) / 3
    high = (4 + 3 + 4) / 3
    expected = (high - low) / 4
    rng = np.random.default_rng(0)
    for _ in range(20):
        order = rng.permutation(item.size)
        assert es.upper_lower_index(item[order], rest[order], item_max=4) == pytest.approx(expected, abs=1e-12)
