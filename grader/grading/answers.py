"""Reading submitted answer values: numbers with units, pole lists, controller designs.

Every reader takes the raw JSON/YAML/XLSX value (untrusted: any type) and either
returns a typed value or raises :class:`AnswerError` with a student-facing reason.
A unit of the wrong dimension is not an error here: :func:`to_unit` returns None.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import pint

from grader.errors import GraderError, UnitError
from grader.grading.limits import DEFAULT_LIMITS, Limits
from grader.units import Q_, parse_quantity, parse_unit, ureg


class AnswerError(GraderError):
    """An answer value cannot be read (the item is graded ``invalid``)."""


def is_blank(raw: Any) -> bool:
    """No answer: absent, null or an empty string."""
    return raw is None or (isinstance(raw, str) and not raw.strip())


_SIMPLE = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d{1,3})?)\s*([A-Za-z%][A-Za-z0-9_*/^() ]*)?\s*$")


@lru_cache(maxsize=512)
def _unit(text: str) -> pint.Unit:
    return parse_unit(text, where="unit")


def _fast_quantity(raw: str, unit: str) -> pint.Quantity | None:
    """``"<number> <unit>"`` without pint's expression parser (units are cached); None if not that simple."""
    m = _SIMPLE.match(raw) if len(raw) <= 120 else None
    if m is None:
        return None
    value = float(m.group(1))
    try:
        return Q_(value, _unit(m.group(2).strip()) if m.group(2) else _unit(unit)) if math.isfinite(value) else None
    except UnitError:
        return None


def read_quantity(raw: Any, *, unit: str, what: str) -> pint.Quantity:
    """A number with a unit (``"0.0385 in^3/s/mA"``) or a bare number, taken in ``unit``."""
    if isinstance(raw, bool) or not isinstance(raw, (str, int, float)):
        raise AnswerError(f"{what}: expected a number with a unit, got {_type_name(raw)}")
    if isinstance(raw, float) and not math.isfinite(raw):
        raise AnswerError(f"{what}: {raw} is not a finite number")
    fast = _fast_quantity(raw, unit) if isinstance(raw, str) else None
    if fast is not None:
        return fast
    try:
        return parse_quantity(raw, where=what, default_unit=unit)
    except UnitError as exc:
        raise AnswerError(str(exc)) from None
    except Exception:  # noqa: BLE001 - pint's parser leaks AssertionError, TokenError on odd input
        raise AnswerError(f"{what}: cannot read {str(raw)[:40]!r} as a number with a unit") from None


def _type_name(raw: Any) -> str:
    return {list: "a list", dict: "a table (mapping)", bool: "true/false"}.get(type(raw), type(raw).__name__)


def to_unit(q: pint.Quantity, unit: str) -> float | None:
    """``q`` as a float in ``unit``; None when the dimensions differ.

    Hz (cycles per second) converts to rad/s with 2π, not 1 as pint's radian-as-1 would.
    """
    factor = _conversion(q.units, unit)
    if factor is None:
        return None
    value = float(q.magnitude) * factor
    return value if math.isfinite(value) else None


@lru_cache(maxsize=1024)
def _conversion(units: pint.Unit, unit: str) -> float | None:
    """The factor from ``units`` to ``unit`` (None across dimensions); Hz counts as turn/s against radians."""
    target = ureg.parse_units(unit)
    q = Q_(1.0, units)
    if "radian" in target._units and "hertz" in units._units:
        q = Q_(q.to("Hz").magnitude, "turn/s")
    try:
        return float(q.to(target).magnitude)
    except pint.errors.DimensionalityError:
        return None


# ---------------------------------------------------------------- poles
_NUM = r"(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_COMPLEX = re.compile(rf"^(?P<re>[-+]?{_NUM})?"
                      rf"(?:(?P<sign>[-+]|±)(?P<im>{_NUM})?\*?[ij]|(?P<sign2>[-+]|±)[ij]\*?(?P<im2>{_NUM}))?$")
_IMAG_ONLY = re.compile(rf"^(?P<sign>[-+]|±)?(?P<im>{_NUM})?\*?[ij]$")


def _finite(x: Any, what: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float, str)):
        raise AnswerError(f"{what}: expected a number, got {_type_name(x)}")
    try:
        v = float(x)
    except ValueError:
        raise AnswerError(f"{what}: {str(x)[:40]!r} is not a number") from None
    if not math.isfinite(v):
        raise AnswerError(f"{what}: {x} is not a finite number")
    return v


def parse_pole(raw: Any, what: str) -> list[complex]:
    """One pole, or a conjugate pair for ``"a ± bj"``: numbers, ``[re, im]``, ``{re, im}`` or text."""
    if isinstance(raw, (list, tuple)) and len(raw) == 2:
        return [complex(_finite(raw[0], what), _finite(raw[1], what))]
    if isinstance(raw, dict) and set(raw) == {"re", "im"}:
        return [complex(_finite(raw["re"], what), _finite(raw["im"], what))]
    if isinstance(raw, (int, float)) and not isinstance(raw, bool):
        return [complex(_finite(raw, what), 0.0)]
    if not isinstance(raw, str) or len(raw) > 80:
        raise AnswerError(f"{what}: expected a pole such as '-25.8+153.6j' or '-25.8 ± 153.6j'")
    text = re.sub(r"\s+", "", raw).replace("+/-", "±").replace("+-", "±").strip("()")
    m = _COMPLEX.match(text) or _IMAG_ONLY.match(text)
    if not m or not text:
        raise AnswerError(f"{what}: cannot read {raw!r} as a pole (write e.g. -25.8+153.6j or -25.8 ± 153.6j)")
    g = m.groupdict()
    re_part = float(g.get("re") or 0.0)
    sign = g.get("sign") or g.get("sign2")
    im_text = g.get("im") or g.get("im2")
    has_imag = sign is not None or text.endswith(("j", "i"))
    im = float(im_text) if im_text else (1.0 if has_imag else 0.0)
    if sign == "-":
        im = -im
    values = [complex(re_part, im)] + ([complex(re_part, -im)] if sign == "±" else [])
    if not all(math.isfinite(v.real) and math.isfinite(v.imag) for v in values):
        raise AnswerError(f"{what}: {raw!r} is not finite")
    return values


@dataclass(frozen=True)
class Gains:
    """Controller gains in the key's gain convention."""

    Kp: float
    Ki: float = 0.0
    Kd: float = 0.0

    def matches(self, other: Gains, rel: float = 1e-3) -> bool:
        return all(abs(a - b) <= rel * max(abs(a), abs(b), 1e-9) for a, b in
                   ((self.Kp, other.Kp), (self.Ki, other.Ki), (self.Kd, other.Kd)))


def _gain_key(text: Any, what: str) -> Gains:
    if isinstance(text, str):
        m = re.fullmatch(r"\s*(?:Kp\s*=\s*)?(.+?)\s*", text)
        text = m.group(1) if m else text
    return Gains(Kp=_finite(text, what))


def read_poles(raw: Any, *, limits: Limits = DEFAULT_LIMITS) -> list[tuple[Gains, list[complex]]]:
    """Poles per gain: ``[{Kp, Ki?, Kd?, poles: [...]}, ...]`` or ``{"10": [...], "Kp=25": [...]}``."""
    if isinstance(raw, dict):
        entries = [(_gain_key(k, f"closed_loop_poles key {str(k)[:20]!r}"), v) for k, v in raw.items()]
    elif isinstance(raw, list):
        entries = [_pole_entry(e, i) for i, e in enumerate(raw[: limits.max_gains + 1])]
    elif isinstance(raw, str):
        raise AnswerError(f"closed_loop_poles: cannot read {raw[:40]!r}: write one gain a line, as "
                          "Kp=10: -20+150j, -20-150j, -12 (in a file: a list of {Kp, poles} entries)")
    else:
        raise AnswerError(f"closed_loop_poles: expected a list of {{Kp, poles}} entries, got {_type_name(raw)}")
    if len(entries) > limits.max_gains:
        raise AnswerError(f"closed_loop_poles: more than {limits.max_gains} gains")
    out = []
    for n, (gains, poles) in enumerate(entries, start=1):
        where = f"closed_loop_poles: entry {n} (Kp = {gains.Kp:g}, Ki = {gains.Ki:g}, Kd = {gains.Kd:g})"
        if not isinstance(poles, list) or not poles:
            raise AnswerError(f"{where}: expected a list of poles")
        if len(poles) > limits.max_poles:
            raise AnswerError(f"{where}: more than {limits.max_poles} poles")
        out.append((gains, [p for i, x in enumerate(poles) for p in parse_pole(x, f"{where}, pole {i + 1}")]))
    return out


def _pole_entry(e: Any, i: int) -> tuple[Gains, Any]:
    what = f"closed_loop_poles entry {i + 1}"
    if not isinstance(e, dict) or "Kp" not in e or "poles" not in e:
        raise AnswerError(f"{what}: expected {{Kp: ..., poles: [...]}} (Ki and Kd optional)")
    unknown = set(e) - {"Kp", "Ki", "Kd", "poles"}
    if unknown:
        raise AnswerError(f"{what}: unknown field(s) {', '.join(sorted(map(str, unknown)))}")
    gains = Gains(*(_finite(e.get(k, 0.0), f"{what}.{k}") for k in ("Kp", "Ki", "Kd")))
    return gains, e["poles"]


# ---------------------------------------------------------------- designs
#: design item -> (gain fields, claim field, claim unit)
DESIGN_FIELDS: dict[str, tuple[tuple[str, ...], str, str]] = {
    "pd_design": (("Kp", "Kd"), "overshoot", "percent"),
    "pi_design": (("Kp", "Ki"), "ramp_error", "in"),
}


@dataclass(frozen=True)
class DesignAnswer:
    """Submitted gains and the claimed overshoot [fraction] or ramp error [in]."""

    gains: Gains
    claim: float | None


def gain_units(gain_unit: str) -> dict[str, str]:
    """Units of Kp, Ki, Kd given the unit of a P gain (``dimensionless`` or ``V/in``)."""
    base = "" if gain_unit == "dimensionless" else f"{gain_unit}*"
    return {"Kp": gain_unit, "Ki": f"{base}1/s", "Kd": f"{base}s"}


def read_design(raw: Any, *, item: str, gain_unit: str) -> DesignAnswer:
    """``{Kp, Kd, overshoot}`` (pd_design) or ``{Kp, Ki, ramp_error}`` (pi_design)."""
    names, claim_name, claim_unit = DESIGN_FIELDS[item]
    if isinstance(raw, str):
        example = ", ".join(f"{n} = …" for n in (*names, claim_name))
        raise AnswerError(f"{item}: cannot read {raw[:40]!r}: write {example} (in a file: a table with "
                          f"{', '.join(names)} and {claim_name})")
    if not isinstance(raw, dict):
        raise AnswerError(f"{item}: expected a table with {', '.join(names)} and {claim_name}, got {_type_name(raw)}")
    unknown = set(raw) - {*names, claim_name}
    if unknown:
        raise AnswerError(f"{item}: unknown field(s) {', '.join(sorted(map(str, unknown)))}")
    units = gain_units(gain_unit)
    values: dict[str, float] = {}
    for name in names:
        if is_blank(raw.get(name)):
            raise AnswerError(f"{item}: {name} is missing")
        q = read_quantity(raw[name], unit=units[name], what=f"{item}.{name}")
        v = to_unit(q, units[name])
        if v is None or v < 0:
            raise AnswerError(f"{item}.{name}: {raw[name]!r} is not a non-negative gain in {units[name]}")
        values[name] = v
    if values["Kp"] <= 0:
        raise AnswerError(f"{item}.Kp: the proportional gain must be positive")
    claim = None
    if not is_blank(raw.get(claim_name)):
        q = read_quantity(raw[claim_name], unit=claim_unit, what=f"{item}.{claim_name}")
        claim = to_unit(q, "dimensionless" if claim_unit == "percent" else claim_unit)
        if claim is None:
            raise AnswerError(f"{item}.{claim_name}: {raw[claim_name]!r} should be in {claim_unit}")
    return DesignAnswer(Gains(Kp=values["Kp"], Ki=values.get("Ki", 0.0), Kd=values.get("Kd", 0.0)), claim)
