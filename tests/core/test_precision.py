"""The written precision: 6 significant digits, idempotent, a shared grid for a pole's parts."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from grader.precision import SIGNIFICANT_DIGITS, round_group, round_sig, rounded

finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False).filter(lambda x: x == 0 or abs(x) > 1e-12)


@given(finite)
def test_round_sig_is_close_and_idempotent(x: float) -> None:
    y = round_sig(x)
    assert abs(y - x) <= 0.5 * 10 ** (1 - SIGNIFICANT_DIGITS) * abs(x) * (1 + 1e-12)
    assert round_sig(y) == y
    assert len(repr(abs(y)).replace(".", "").replace("0", "")) <= SIGNIFICANT_DIGITS + 4  # no float tail


@given(finite, finite)
def test_round_group_shares_the_grid_of_the_largest_part(a: float, b: float) -> None:
    ra, rb = round_group([a, b])
    scale = max(abs(a), abs(b))
    for x, y in ((a, ra), (b, rb)):
        assert abs(y - x) <= 0.5 * 10 ** (math.floor(math.log10(scale)) - SIGNIFICANT_DIGITS + 1) * (1 + 1e-9) if scale else y == 0
    assert rounded([ra, rb]) == [ra, rb]  # the writer's final pass leaves it alone


def test_numerical_zero_beside_a_large_part_is_zero_and_cpu_noise_vanishes() -> None:
    assert round_group([-3.552713678800501e-15, 157.8173686083622]) == [0.0, 157.817]
    assert round_group([-1.7763568394002505e-15, -157.8173686083622]) == [0.0, -157.817]
    assert round_sig(-64.48214084147209) == round_sig(-64.48214084147206) == -64.4821


def test_rounded_walks_json_trees_and_leaves_other_values() -> None:
    tree = {"a": [1.23456789, {"b": 2}], "c": None, "d": True, "e": "x", "f": float("nan")}
    out = rounded(tree)
    assert out["a"] == [1.23457, {"b": 2}] and out["c"] is None and out["d"] is True and out["e"] == "x"
    assert math.isnan(out["f"])
