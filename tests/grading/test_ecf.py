"""Error carried forward recomputes from the student's values with the students' own procedure."""

from __future__ import annotations

import pytest

from grader.grading.context import KeyContext
from grader.grading.ecf import recompute, student_model
from grader.grading.mistakes import CATALOG, Env, wrong_value
from grader.model.linear import closed_loop_poles
from grader.model.params import Controller


def test_key_values_reproduce_the_key(kc: KeyContext) -> None:
    """To the key's precision: each input is written at 6 significant digits (≤ 5e-7 each)."""
    assert recompute("beta_over_Vt", kc, {}) == pytest.approx(kc.value("beta_over_Vt"), rel=5e-6)
    assert recompute("Kce", kc, {}) == pytest.approx(kc.value("Kce"), rel=5e-6)


def test_coefficient_matching_scales_as_the_physics_says(kc: KeyContext) -> None:
    """β/Vt = Mω²/(4A²) does not depend on Kq; Kce = Kc·A/(Mω²) is proportional to Kq and to 1/ω²."""
    kq, w = kc.value("Kq"), kc.value("omega_crit")
    bv, kce = recompute("beta_over_Vt", kc, {}), recompute("Kce", kc, {})
    assert recompute("beta_over_Vt", kc, {"Kq": 2 * kq}) == pytest.approx(bv, rel=1e-9)
    assert recompute("Kce", kc, {"Kq": 2 * kq}) == pytest.approx(2 * kce, rel=1e-9)
    assert recompute("Kce", kc, {"omega_crit": w / 2}) == pytest.approx(4 * kce, rel=1e-9)
    assert recompute("beta_over_Vt", kc, {"omega_crit": w / 2}) == pytest.approx(bv / 4, rel=1e-9)


def test_poles_from_the_students_model(kc: KeyContext) -> None:
    own = {"Kq": 0.05, "Kce": 1e-3}
    runs = recompute("closed_loop_poles", kc, own)
    p = student_model(kc, own)
    first = runs[0]
    expected = closed_loop_poles(p, Controller(first["Kp"], first["Ki"], first["Kd"]))
    assert sorted(complex(*z).imag for z in first["poles"]) == pytest.approx(sorted(expected.imag))


def test_impossible_upstream_values_give_no_ecf(kc: KeyContext) -> None:
    assert recompute("Kce", kc, {"omega_crit": -1.0}) is None
    assert recompute("Kp_no_overshoot", kc, {"Kq": -1.0}) is None
    assert recompute("Kq", kc, {}) is None


@pytest.mark.parametrize("code", sorted(c for c, m in CATALOG.items() if not set(m.items) <= {"closed_loop_tf", "open_loop_tf", "char_poly"}))
def test_every_numeric_mistake_is_told_apart_from_the_key(code: str, kc: KeyContext) -> None:
    for item in CATALOG[code].items:
        if item in ("closed_loop_tf", "open_loop_tf", "char_poly"):
            continue
        w = wrong_value(code, Env(kc, "volts"), item)
        assert w is not None, item
        if isinstance(w, float):
            assert abs(w - kc.value(item)) > 0.1 * abs(kc.value(item)), (item, w)
