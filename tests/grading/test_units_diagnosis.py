"""Unit-slip candidates are derived from the item's unit, and recognised when (and only when) they fit."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grader.grading.units_diagnosis import base_exponents, diagnose_slip, slip_candidates
from grader.units import Q_, ureg


@pytest.mark.parametrize(("unit", "factor", "used", "needed"), [
    ("in**3/s/mA", 1 / 1728, "ft³", "in³"),
    ("in**3/s/mA", 1728, "ft³", "in³"),
    ("in**3/s/mA", 1000, "1/A", "1/mA"),
    ("in**3/s", 60 / 231, "gal, 1/min", "in³, 1/s"),
    ("psi/in**3", 6894.757, "Pa", "psi"),
    ("psi/in**3", 386.0886, "in·lb/s²", "lbf"),
    ("in**3/s/psi", 1 / 386.0886, "s²/in/lb", "1/lbf"),
    ("rad/s", 1 / (2 * math.pi), "turn/s", "rad/s"),
    ("in", 25.4, "mm", "in"),
    ("lbf*s/in", 4.448222, "N", "lbf"),
])
def test_known_slips_are_recognised(unit: str, factor: float, used: str, needed: str) -> None:
    slip = diagnose_slip(3.7 * factor, 3.7, unit, rel_tol=0.02)
    assert slip is not None and slip.factor == pytest.approx(factor, rel=1e-4)
    assert (slip.used, slip.needed) == (used, needed)


def test_weight_as_mass_is_named() -> None:
    slip = diagnose_slip(21500 * 386.09, 21500, "psi/in**3", rel_tol=0.05)
    assert slip is not None and "weight" in slip.phrase and "mass" in slip.phrase


@pytest.mark.parametrize("unit", ["in**3/s/mA", "psi/in**3", "in**3/s/psi", "rad/s", "in", "V/in", "lbf*s/in", "in**3/s"])
def test_every_single_slip_is_a_conversion_between_units_of_one_dimension(unit: str) -> None:
    for slip in slip_candidates(unit):
        for used, needed in zip(slip.used.split(", "), slip.needed.split(", ")):
            u, n = (ureg.parse_units(x.replace("²", "**2").replace("³", "**3").replace("·", "*")) for x in (used, needed))
            assert u.dimensionality == n.dimensionality, slip


def test_base_exponents_use_the_course_units() -> None:
    assert base_exponents("psi/in**3") == {"lbf": 1, "in": -5}
    assert base_exponents("in**3/s/psi") == {"in": 5, "s": -1, "lbf": -1}
    assert base_exponents("V/in") == {"V": 1, "in": -1}


@settings(max_examples=60, deadline=None)
@given(st.floats(1e-6, 1e6), st.sampled_from(["in**3/s/mA", "psi/in**3", "in**3/s/psi", "in"]), st.data())
def test_candidates_are_found_and_nothing_close_to_one_is_a_slip(expected: float, unit: str, data: st.DataObject) -> None:
    slip = data.draw(st.sampled_from(slip_candidates(unit)))
    found = diagnose_slip(expected * slip.factor, expected, unit, rel_tol=0.02)
    assert found is not None and found.factor == pytest.approx(slip.factor, rel=0.04)
    assert diagnose_slip(expected * data.draw(st.floats(0.96, 1.04)), expected, unit, rel_tol=0.02) is None


def test_no_diagnosis_for_sign_errors_zero_or_dimensionless() -> None:
    assert diagnose_slip(-1728.0, 1.0, "in**3/s/mA", rel_tol=0.02) is None
    assert diagnose_slip(0.0, 1.0, "in**3/s/mA", rel_tol=0.02) is None
    assert diagnose_slip(1000.0, 1.0, "dimensionless", rel_tol=0.02) is None


def test_gpm_factor_is_pints_own() -> None:
    slip = diagnose_slip(Q_(1, "in**3/s").to("gpm").magnitude, 1.0, "in**3/s", rel_tol=0.01)
    assert slip is not None and slip.factor == pytest.approx(Q_(1, "in**3/s").to("gpm").magnitude)
