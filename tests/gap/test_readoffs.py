"""Read-offs are written on their run's grid: the same bytes on every CPU."""

from __future__ import annotations

from grader.gap.build import _on_grid


def test_a_numerical_zero_beside_the_runs_scale_is_written_as_zero() -> None:
    # two CPUs' steady-state errors of a model that settles exactly: -6.09948e-10 and -6.09946e-10 in
    a = _on_grid([-1.01528e-05, 1.36157e-09, -6.09948e-10], 0.06)
    b = _on_grid([-1.01528e-05, 1.36157e-09, -6.09946e-10], 0.06)
    assert a == b == [-1.02e-05, 0.0, 0.0]


def test_quantities_without_a_grid_keep_six_significant_digits() -> None:
    assert _on_grid([23.4567891, 23.41], None) == [23.4568, 23.41]
