"""The package's single pint registry, safe quantity parsing, and the course's units.

Quantities carry units at every boundary (files, CLI, reports). Numeric work uses
plain floats in one coherent inch-pound-second system, the course's own:

======================  ============================
quantity kind           internal (and display) unit
======================  ============================
length                  in
force                   lbf
mass                    lbf*s**2/in
time                    s
pressure                psi
current                 mA
voltage                 V
flow                    in**3/s
======================  ============================

Everything else (Kq in in³/s/mA, β/Vt in psi/in³, Kce in in³/s/psi, …) follows.
"""

from __future__ import annotations

import math
import re
from typing import Final

import pint

from grader.errors import UnitError

ureg: Final = pint.UnitRegistry(autoconvert_offset_to_baseunit=True)
ureg.define("gpm = gallon / minute")
Q_ = ureg.Quantity
Quantity = pint.Quantity

_MAX_LEN: Final = 120
_ALLOWED = re.compile(r"^[A-Za-z0-9_.+\-*/^()\s°µ%]*$")
_BIG_NUMBER = re.compile(r"\d{40,}")
#: every power: its base's last character, and the exponent text up to the next operator
_POWER = re.compile(r"(\S?)\s*\*\*\s*(\(?\s*[-+]?[^*/()\s]*\s*\)?)(\s*\*\*)?")
_MAX_EXPONENT: Final = 12


def _check_powers(text: str, where: str) -> None:
    """Allow only ``unit ** small integer``: no power of a number, no tower, |n| <= 12
    (pint evaluates powers exactly, so ``9**9**9`` would hang)."""
    for m in _POWER.finditer(text.replace("^", "**")):
        base, exponent, tower = m.group(1), m.group(2).strip("() \t"), m.group(3)
        if tower or base.isdigit() or base == "." or not re.fullmatch(r"[-+]?\d{1,2}", exponent) \
                or abs(int(exponent)) > _MAX_EXPONENT:
            raise UnitError(f"{where}: {text!r}: only a unit raised to a small whole power (up to {_MAX_EXPONENT}) is allowed")


def _guard(text: str, where: str) -> str:
    if not isinstance(text, str):
        raise UnitError(f"{where}: expected a quantity string, got {type(text).__name__}")
    text = text.strip()
    if not text:
        raise UnitError(f"{where}: empty quantity")
    if len(text) > _MAX_LEN:
        raise UnitError(f"{where}: quantity string longer than {_MAX_LEN} characters")
    if not _ALLOWED.match(text):
        raise UnitError(f"{where}: {text!r} contains characters not allowed in a quantity")
    if _BIG_NUMBER.search(text):
        raise UnitError(f"{where}: {text!r} has a number too large")
    _check_powers(text, where)
    return text


def parse_quantity(text: str | float | int, *, where: str = "quantity", default_unit: str | None = None) -> pint.Quantity:
    """Parse ``"0.0385 in^3/s/mA"`` (or a bare number with ``default_unit``) into a Quantity.

    Raises :class:`UnitError` naming ``where`` for anything pint cannot parse.
    """
    if isinstance(text, bool):
        raise UnitError(f"{where}: expected a number with a unit, got a boolean")
    if isinstance(text, (int, float)):
        if not math.isfinite(float(text)):
            raise UnitError(f"{where}: value is not a finite number")
        return Q_(float(text), default_unit or "dimensionless")
    text = _guard(text, where)
    try:
        q = ureg.parse_expression(text.replace("^", "**"))
    except Exception as exc:  # pint's parser raises many types (even AssertionError) on hostile text
        raise UnitError(f"{where}: cannot parse {text!r} as a quantity ({type(exc).__name__})") from None
    if not isinstance(q, pint.Quantity):
        q = Q_(float(q), default_unit or "dimensionless")
    elif not q._units and default_unit is not None:  # no unit written at all (not even %, ppm)
        q = Q_(float(q.magnitude), default_unit)
    if not math.isfinite(float(q.magnitude)):
        raise UnitError(f"{where}: value is not a finite number")
    return q


def parse_unit(text: str, *, where: str = "unit") -> pint.Unit:
    """Parse a unit string such as ``"L/min"``; raises :class:`UnitError`."""
    text = _guard(text, where)
    try:
        q = ureg.parse_expression(text.replace("^", "**"))
    except Exception as exc:  # as above
        raise UnitError(f"{where}: unknown unit {text!r} ({type(exc).__name__})") from None
    if isinstance(q, pint.Quantity):
        if float(q.magnitude) != 1.0:
            raise UnitError(f"{where}: {text!r} is a quantity, not a unit")
        return q.units
    raise UnitError(f"{where}: {text!r} is a number, not a unit")


def to_float(q: pint.Quantity, unit: str, *, where: str = "quantity") -> float:
    """Convert ``q`` to a plain float in ``unit``; a dimension mismatch raises :class:`UnitError`."""
    try:
        return float(q.to(unit).magnitude)
    except pint.errors.DimensionalityError:
        raise UnitError(
            f"{where}: {q:~P} has dimension {q.dimensionality}, expected {ureg.parse_units(unit).dimensionality} ({unit})"
        ) from None


def quantity_to_float(text: str | float | int, unit: str, *, where: str = "quantity") -> float:
    """Parse ``text`` and convert it to ``unit`` (bare numbers are taken in ``unit``)."""
    return to_float(parse_quantity(text, where=where, default_unit=unit), unit, where=where)


def fmt(value: float, unit: str, digits: int = 4) -> str:
    """Format a float already in ``unit`` as ``"0.03850 in³/s/mA"`` for reports."""
    pretty = f"{ureg.Unit(unit):~P}" if unit != "dimensionless" else ""
    return f"{value:.{digits}g} {pretty}".strip()
