"""The "rated highest" sentence claims only what the tests support."""

from __future__ import annotations

import numpy as np

from grader.assess import stats
from grader.assess.claims import fmt_p, highest_claim
from grader.assess.stats import FriedmanResult, PairResult

NAMES = {"a": "Alpha", "b": "Beta", "c": "Gamma"}
SIGNIFICANT = FriedmanResult(n=40, k=3, chi2=20.0, df=2, p=0.00005, kendall_w=0.25)


def _pairs(p_ab: float, p_ac: float, diff_ab: float = 1.0) -> list[PairResult]:
    return [
        PairResult("a", "b", 40, 100.0, p_ab, p_ab, diff_ab),
        PairResult("a", "c", 40, 100.0, p_ac, p_ac, 1.0),
        PairResult("b", "c", 40, 100.0, 0.5, 0.5, 0.0),
    ]


def test_claim_supported_only_when_every_pair_is_significant() -> None:
    top, ok, text = highest_claim("Simulink", {"a": 4.5, "b": 3.9, "c": 3.1}, SIGNIFICANT, _pairs(0.01, 0.001), NAMES)
    assert (top, ok) == ("a", True)
    assert text.startswith('The data support the claim that the Alpha lab was rated highest on "Simulink"')
    assert "largest Holm p = 0.01)" in text


def test_one_non_significant_pair_blocks_the_claim() -> None:
    top, ok, text = highest_claim("Simulink", {"a": 4.5, "b": 4.4, "c": 3.1}, SIGNIFICANT, _pairs(0.21, 0.001), NAMES)
    assert (top, ok) == ("a", False)
    assert text.startswith("The data do not support the claim that the Alpha lab was rated highest")
    assert "its difference from Beta is not significant after Holm correction (p = 0.21, n = 40 paired)" in text


def test_non_significant_friedman_blocks_the_claim() -> None:
    weak = FriedmanResult(n=12, k=3, chi2=2.0, df=2, p=0.37, kendall_w=0.08)
    _, ok, text = highest_claim("Time", {"a": 4.0, "b": 3.0, "c": 3.0}, weak, _pairs(0.01, 0.01), NAMES)
    assert not ok and "the labs do not differ significantly" in text and "n = 12 students" in text


def test_paired_direction_must_agree() -> None:
    _, ok, text = highest_claim("Time", {"a": 4.0, "b": 3.9, "c": 3.0}, SIGNIFICANT, _pairs(0.01, 0.01, -0.5), NAMES)
    assert not ok and "rated Beta higher" in text


def test_ties_and_missing_tests() -> None:
    top, ok, text = highest_claim("Time", {"a": 4.0, "b": 4.0, "c": 3.0}, SIGNIFICANT, _pairs(1, 0.01), NAMES)
    assert (top, ok) == (None, False) and "Alpha and Beta tie" in text
    _, ok, text = highest_claim("Time", {"a": 4.0, "b": 3.0, "c": None}, None, _pairs(0.01, 0.01), NAMES)
    assert not ok and "too few students rated every lab" in text
    _, ok, _ = highest_claim("Time", {"a": 4.0, "b": None, "c": None}, None, [], NAMES)
    assert not ok


def test_clear_difference_in_real_data_is_claimed() -> None:
    rng = np.random.default_rng(3)
    base = rng.integers(2, 4, size=50).astype(float)
    columns = {"a": np.minimum(base + 2, 5), "b": base, "c": np.maximum(base - 1, 1)}
    friedman = stats.friedman(np.column_stack(list(columns.values())))
    pairs = stats.pairwise_wilcoxon(columns)
    means = {k: float(v.mean()) for k, v in columns.items()}
    assert highest_claim("S", means, friedman, pairs, NAMES)[1] is True


def test_p_value_formatting() -> None:
    assert [fmt_p(p) for p in (None, 0.0004, 0.0052, 0.0496, 0.04999, 0.27846, 0.5)] == [
        "p not available", "p < 0.001", "p = 0.0052", "p = 0.0496", "p = 0.04999", "p = 0.278", "p = 0.5"
    ]
