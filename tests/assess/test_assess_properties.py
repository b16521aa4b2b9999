"""Properties of the survey statistics (hypothesis)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.assess import stats

ratings = st.lists(st.one_of(st.none(), st.integers(1, 5)), min_size=1, max_size=80)
matrices = st.integers(3, 40).flatmap(
    lambda n: st.lists(st.lists(st.integers(1, 5), min_size=n, max_size=n), min_size=2, max_size=6)
)


@given(ratings)
def test_percentages_sum_to_100_and_counts_to_n(values: list[int | None]) -> None:
    s = stats.likert_summary(np.array([np.nan if v is None else v for v in values], dtype=float), points=5)
    assert s.n == sum(v is not None for v in values) == sum(s.counts)
    if s.n:
        assert s.pct_disagree + s.pct_neutral + s.pct_agree == pytest.approx(100.0)
    else:
        assert s.pct_agree is None


@settings(max_examples=60)
@given(matrices, st.randoms(use_true_random=False))
def test_alpha_is_invariant_to_item_order_and_shifts(columns: list[list[int]], rnd) -> None:
    matrix = np.array(columns, dtype=float).T
    alpha = stats.cronbach_alpha(matrix)
    order = list(range(matrix.shape[1]))
    rnd.shuffle(order)
    shuffled = stats.cronbach_alpha(matrix[:, order])
    shifted = stats.cronbach_alpha(matrix + np.arange(matrix.shape[1]))
    if alpha is None:
        assert shuffled is None and shifted is None
    else:
        assert shuffled == pytest.approx(alpha, abs=1e-9)
        assert shifted == pytest.approx(alpha, abs=1e-9)
        assert alpha <= 1.0 + 1e-12


@settings(max_examples=60)
@given(matrices)
def test_kendall_w_lies_between_0_and_1(columns: list[list[int]]) -> None:
    result = stats.friedman(np.array(columns, dtype=float).T)
    if result is not None:
        assert -1e-12 <= result.kendall_w <= 1 + 1e-12
        assert 0.0 <= result.p <= 1.0


@settings(max_examples=10, deadline=None)  # multipletests runs gc.collect() on every call: slow
@given(st.lists(st.floats(0, 1), min_size=1, max_size=12))
def test_holm_never_lowers_p_values(pvalues: list[float]) -> None:
    adjusted = stats.holm(pvalues)
    assert all(p <= a <= 1.0 for p, a in zip(pvalues, adjusted, strict=True))
