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



def _registry() -> pint.UnitRegistry:
    """The registry, its parsed definitions cached on disk by pint (start-up ~8x faster); without
    a writable cache folder, built from the definitions file as before."""
    try:
        return pint.UnitRegistry(autoconvert_offset_to_baseunit=True, cache_folder=":auto:")
    except Exception:  # noqa: BLE001 - any cache problem (read-only home, corrupt file): no cache
        return pint.UnitRegistry(autoconvert_offset_to_baseunit=True)


ureg: Final = _registry()
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
        raw = m.group(2).strip()
        base, exponent, tower = m.group(1), raw.strip("() \t"), m.group(3)
        if raw.startswith("(") and not raw.endswith(")"):  # (1/3): the match stopped at the '/'
            exponent = ""
        if tower or base.isdigit() or base == "." or not re.fullmatch(r"[-+]?\d{1,2}", exponent) \
                or abs(int(exponent)) > _MAX_EXPONENT:
            raise UnitError(f"{where}: {text!r}: only a unit raised to a small whole power (up to {_MAX_EXPONENT}) is allowed")


_SUPERSCRIPTS = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹⁻", "0123456789-")
_SUPER_RUN = re.compile("[⁻⁰¹²³⁴⁵⁶⁷⁸⁹]+")
#: Operators as the reports print them (lbf·s/in) or word processors type them; expressions read them too.
SIGNS = {"−": "-", "×": "*", "·": "*", "⋅": "*", "÷": "/"}
_SIGNS = str.maketrans(SIGNS)
#: A power of ten written out (2.23×10⁻⁵, as the preview prints small numbers): read as 2.23e-5.
_TIMES_TEN = re.compile(r"(\d)\s*\*\s*10\^([-+]?\d+)")


def plain_powers(text: str) -> str:
    """Superscript powers as ``^`` powers (``in³`` -> ``in^3``, ``s⁻¹`` -> ``s^-1``): what the reports print
    reads back."""
    return _SUPER_RUN.sub(lambda m: "^" + m.group().translate(_SUPERSCRIPTS), text)


def _guard(text: str, where: str) -> str:
    if not isinstance(text, str):
        raise UnitError(f"{where}: expected a quantity string, got {type(text).__name__}")
    text = _TIMES_TEN.sub(r"\1e\2", plain_powers(text.strip()).translate(_SIGNS))
    if not text:
        raise UnitError(f"{where}: empty quantity")
    if len(text) > _MAX_LEN:
        raise UnitError(f"{where}: quantity string longer than {_MAX_LEN} characters")
    if not _ALLOWED.match(text):
        bad = next(c for c in text if not _ALLOWED.match(c))
        hint = " (a decimal comma? write 0.04)" if bad == "," else ""
        raise UnitError(f"{where}: {text!r} contains {bad!r}, which a quantity cannot hold{hint}")
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
        if isinstance(text, int) and abs(text) > 10**300:  # float() would overflow
            raise UnitError(f"{where}: a number too large ({len(str(abs(text)))} digits)")
        if not math.isfinite(float(text)):
            raise UnitError(f"{where}: value is not a finite number")
        return Q_(float(text), default_unit or "dimensionless")
    text = _guard(text, where)
    try:
        q = ureg.parse_expression(text.replace("^", "**"))
    except ZeroDivisionError:
        raise UnitError(f"{where}: {text!r} divides by zero") from None
    except Exception:  # pint's parser raises many types (even AssertionError) on hostile text
        raise UnitError(f"{where}: cannot read {text!r} as a number with a unit{_did_you_mean(text)}") from None
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
    except ZeroDivisionError:
        raise UnitError(f"{where}: {text!r} divides by zero") from None
    except Exception:  # as above
        raise UnitError(f"{where}: unknown unit {text!r}{_did_you_mean(text)}") from None
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
        raise UnitError(f"{where}: {q.units:~P} is {dimension_words(q.units)}; expected {dimension_words(unit)} "
                        f"({pretty_unit(unit)})") from None


def quantity_to_float(text: str | float | int, unit: str, *, where: str = "quantity") -> float:
    """Parse ``text`` and convert it to ``unit`` (bare numbers are taken in ``unit``)."""
    return to_float(parse_quantity(text, where=where, default_unit=unit), unit, where=where)


_SUPERSCRIPT: Final = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def pretty_unit(unit: str) -> str:
    """``in**3/s/mA`` or ``in^3/s/mA`` -> ``in³/s/mA``: the unit as the course writes it, never reordered."""
    if unit == "dimensionless":
        return ""
    text = re.sub(r"\*\*\(?(-?\d+)\)?", lambda m: m.group(1).translate(_SUPERSCRIPT), unit.replace("^", "**"))
    return text.replace(" ", "").replace("*", "·")


def fmt(value: float, unit: str, digits: int = 4) -> str:
    """The one quantity formatter of every report: ``"0.03850 in³/s/mA"``, ``"21570 psi/in³"``
    (``digits`` significant digits, positional from 1e-4 to 1e7, the unit as :func:`pretty_unit` writes it)."""
    return f"{number(value, digits)} {pretty_unit(unit)}".strip()


def number(value: float, digits: int = 4) -> str:
    """``value`` to ``digits`` significant digits, positional between 1e-4 and 1e7, else ``1.234e+08``."""
    if not math.isfinite(value) or value == 0 or not 1e-4 <= abs(value) < 1e7:
        return f"{value:.{digits}g}"
    decimals = digits - 1 - math.floor(math.log10(abs(value)))
    return f"{round(value, decimals):.{max(decimals, 0)}f}"


#: Dimensions a student knows by name, with the course unit that shows each.
_NAMED: Final = (
    ("a frequency", "1/s"), ("a flow", "in**3/s"), ("a velocity", "in/s"), ("an acceleration", "in/s**2"),
    ("a volume", "in**3"), ("an area", "in**2"), ("a length", "in"), ("a time", "s"), ("a voltage", "V"),
    ("a current", "mA"), ("a force", "lbf"), ("a pressure", "psi"), ("a mass", "lbf*s**2/in"),
)


def dimension_words(unit: str | pint.Unit) -> str:
    """The dimension of ``unit`` in words: ``"V/s"`` -> ``"a voltage per time"``, ``"V/in"`` ->
    ``"a voltage per length"``; pint's ``[length]``-style text only when no name fits."""
    dims = (ureg.Unit(unit) if isinstance(unit, str) else unit).dimensionality
    if not dims:
        return "a plain number (no unit)"
    named = [(words, ureg.Unit(u).dimensionality) for words, u in _NAMED]
    for words, d in named:
        if d == dims:
            return words
    for words, d in named:
        for per, e in named:
            if d / e == dims:
                return f"{words} per {per.split(' ', 1)[1]}"
    for words, d in named:
        for per, e in named:
            if d / e == 1 / dims:
                return f"a {per.split(' ', 1)[1]} per {words.split(' ', 1)[1]}".replace("a a", "an a")
    return f"of dimension {dims}"


_UNIT_WORDS: Final = ("in", "ft", "mm", "cm", "m", "s", "ms", "min", "Hz", "rad", "V", "mV", "mA", "A", "lbf", "lb",
                      "N", "psi", "Pa", "kPa", "MPa", "bar", "gal", "gpm", "L", "kg", "g", "deg", "percent")


def _did_you_mean(text: str) -> str:
    """``"; did you mean 'in^3/s/mA'?"`` when a simple repair makes ``text`` readable, else ``""``.

    Repairs: a missing ``^`` before a power (``in3`` -> ``in^3``) and unit names one typo away
    from a common unit (``psii`` -> ``psi``)."""
    import difflib

    fixed = re.sub(r"(?<=[A-Za-z])(\d{1,2})(?![\d.])", r"^\1", text)

    def near(m: re.Match[str]) -> str:
        word = m.group(0)
        try:
            if word in ureg:
                return word
        except Exception:  # noqa: BLE001 - pint's lookup raises on names such as "_"
            return word
        close = difflib.get_close_matches(word, _UNIT_WORDS, n=1, cutoff=0.75)
        return close[0] if close else word

    fixed = re.sub(r"[A-Za-z_µ°]+", near, fixed)
    if fixed == text:
        return ""
    try:
        ureg.parse_expression(_guard(fixed, "suggestion").replace("^", "**"))
    except Exception:  # noqa: BLE001 - the repair did not help; say nothing
        return ""
    unit = re.sub(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*", "", fixed)
    return f"; did you mean {unit or fixed}?"
