"""Unit-slip diagnosis: is a wrong value the right one expressed in another plausible unit?

Candidates are derived from the item's unit, never listed as factors by hand:

1. each factor of the unit as written (``in**3``, ``s``, ``mA``, ``psi``) is swapped, as a
   whole, for the other units of its family (:data:`FAMILIES`: in³ → ft³, gal, L; psi → Pa,
   kPa, bar; mA → A; s → min, ms);
2. the unit is also decomposed into the course's base units (in, lbf, s, mA; ``psi/in³`` →
   lbf·in⁻⁵) and each base factor is swapped whole, or — for lengths — partly (ft for some
   of the inches: a mass in slug = lbf·s²/ft where lbf·s²/in was needed); the force family
   includes lbm·in/s², the weight-used-as-mass slip (a factor g);
3. an angular frequency (``rad/s``) may have been given in Hz or rpm;
4. a product of two slips of different factors as written (gpm = gal/min for in³/s).

The factor of a slip is ``student value / expected value`` when the student's number was
in the slipped unit but labelled (or assumed) in the expected one; the reverse direction
(a conversion applied the wrong way round) is a candidate too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

from grader.units import Q_, ureg

#: confusable units per dimension; an optional label replaces the generic phrase
FAMILIES: dict[str, tuple[tuple[str, str], ...]] = {
    "[length]": (("in", ""), ("ft", ""), ("mm", ""), ("cm", ""), ("m", "")),
    "[length] ** 3": (("in**3", ""), ("ft**3", ""), ("gallon", ""), ("liter", ""), ("cm**3", "")),
    "[time]": (("s", ""), ("min", "")),
    "[current]": (("mA", ""), ("A", "")),
    "[electric_potential]": (("V", ""), ("mV", "")),
    "[force]": (("lbf", ""), ("N", ""),
                ("lb*in/s**2", "a weight in lbf was used as a mass in lbf·s²/in (or lbm for lbf): a factor g")),
    "[pressure]": (("psi", ""), ("Pa", ""), ("kPa", ""), ("MPa", ""), ("bar", "")),
}
_BASE = {"[length]": "in", "[mass]": "lbf", "[time]": "s", "[current]": "mA"}
_ANGULAR = (("turn/s", "a frequency in Hz was given where rad/s were needed (a factor 2π)"),
            ("rpm", "a speed in rpm was given where rad/s were needed"))
_MIN_LOG = 0.05  # slips closer than 5 % to 1 are not told apart from rounding


@dataclass(frozen=True)
class Slip:
    """One explanation: the unit the student seems to have used, the one needed, and the factor.

    ``forward`` is True when the student's number is in ``used`` units (labelled as
    ``needed``), False for the reverse (a conversion applied the wrong way round).
    """

    used: str
    needed: str
    factor: float  # student value / expected value
    phrase: str
    forward: bool = True

    def message(self, item: str, *, reveal_factor: bool = True) -> str:
        ratio = _ratio_text(self.factor) if reveal_factor else "a unit slip away from"
        return f"your {item} is {ratio} the expected value: it looks like {self.phrase}"


def _ratio_text(f: float) -> str:
    return f"{f:.4g}×" if f >= 1 else f"1/{1 / f:.4g} of"


def _pretty(unit: str) -> str:
    return f"{ureg.Unit(unit):~P}"


def _family(dim: str) -> tuple[tuple[str, str], ...]:
    return FAMILIES.get(dim, ())


def _dim_key(unit: str) -> str:
    dims = ureg.Unit(unit).dimensionality
    if dims == ureg.Unit("in**3").dimensionality:
        return "[length] ** 3"
    return next((k for k in FAMILIES if k.startswith("[") and ureg.get_dimensionality(k) == dims), str(dims))


def _swap(u: str, v: str, power: float, label: str) -> list[Slip]:
    """Both directions of using ``v`` where ``u`` was needed, for a factor ``u**power``."""
    f = float(Q_(1.0, u).to(v).magnitude) ** power
    if abs(math.log(f)) < _MIN_LOG:
        return []
    used, needed = _pretty(f"({v})**{power:g}"), _pretty(f"({u})**{power:g}")
    phrase = label or f"{used} were used where {needed} were needed"
    return [Slip(used, needed, f, phrase), Slip(used, needed, 1.0 / f, phrase, forward=False)]


def _written_slips(unit: str) -> list[list[Slip]]:
    """Whole swaps of each factor as written, one group per factor."""
    groups = []
    for name, power in ureg.parse_units(unit)._units.items():
        u = str(ureg.Unit(name))
        groups.append([s for v, label in _family(_dim_key(u)) if ureg.Unit(v) != ureg.Unit(u)
                       for s in _swap(u, v, power, label)])
        if power % 3 == 0 and _dim_key(u) == "[length]":
            groups.append([s for v, label in _family("[length] ** 3") if ureg.Unit(v) != ureg.Unit(f"{u}**3")
                           for s in _swap(f"{u}**3", v, power / 3, label)])
    return groups


def base_exponents(unit: str) -> dict[str, int]:
    """The unit in the course's base units in, lbf, s, mA (volts kept as V)."""
    out: dict[str, int] = {}
    for name, power in ureg.parse_units(unit)._units.items():
        if ureg.Unit(name) == ureg.volt:
            out["V"] = out.get("V", 0) + int(power)
            continue
        dims = ureg.Unit(name).dimensionality
        m = dims.get("[mass]", 0)
        for base, e in (("lbf", m), ("in", dims.get("[length]", 0) - m), ("s", dims.get("[time]", 0) + 2 * m),
                        ("mA", dims.get("[current]", 0))):
            if e:
                out[base] = out.get(base, 0) + int(e * power)
    return {k: v for k, v in out.items() if v}


def _base_slips(unit: str) -> list[list[Slip]]:
    """Whole and (for lengths) partial swaps of each course base factor."""
    groups = []
    dims = {"in": "[length]", "lbf": "[force]", "s": "[time]", "mA": "[current]", "V": "[electric_potential]"}
    for base, power in base_exponents(unit).items():
        group = [s for v, label in _family(dims[base]) if v != base for s in _swap(base, v, power, label)]
        if base == "in" and abs(power) > 1:
            sign = 1 if power > 0 else -1
            for m in range(1, abs(power)):
                group += _swap("in", "ft", sign * m, f"ft and in were mixed (ft for {m} of the {abs(power)} lengths)")
        groups.append(group)
    return groups


def _angular_slips(unit: str) -> list[list[Slip]]:
    units = ureg.parse_units(unit)._units
    if units.get("radian") != 1 or units.get("second") != -1:
        return []
    return [[s for v, label in _ANGULAR for s in _swap("rad/s", v, 1, label)]]


@lru_cache(maxsize=128)
def slip_candidates(unit: str) -> tuple[Slip, ...]:
    """Single slips, then products of two slips of different factors as written (same direction);
    one candidate per distinct factor, the simplest first."""
    groups = [g for g in (*_angular_slips(unit), *_written_slips(unit)) if g]
    singles = [s for g in (*groups, *_base_slips(unit)) for s in g]
    pairs = [Slip(f"{a.used}, {b.used}", f"{a.needed}, {b.needed}", a.factor * b.factor, f"{a.phrase}, and {b.phrase}")
             for i, ga in enumerate(groups) for gb in groups[i + 1:] for a in ga for b in gb if a.forward == b.forward]
    out: list[Slip] = []
    seen: list[float] = []
    for s in singles + pairs:
        key = math.log(s.factor)
        if abs(key) >= _MIN_LOG and all(abs(key - k) > 1e-6 for k in seen):
            out.append(s)
            seen.append(key)
    return tuple(out)


def diagnose_slip(value: float, expected: float, unit: str, *, rel_tol: float) -> Slip | None:
    """The closest slip explaining ``value`` (in ``unit``) against ``expected``, within ``rel_tol``."""
    if expected == 0 or value == 0 or (value > 0) != (expected > 0) or unit == "dimensionless":
        return None
    ratio = math.log(value / expected)
    tol = math.log1p(min(rel_tol, 0.02))
    best = min(slip_candidates(unit), key=lambda s: abs(ratio - math.log(s.factor)), default=None)
    if best is None or abs(ratio - math.log(best.factor)) > tol:
        return None
    return best
