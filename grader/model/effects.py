"""The rig's unmodelled effects: canonical names, parameters, ranges, and parsing.

Canonical effect names (used everywhere: code, CLI, reports, ``truth.json``) and
their parameters, in internal units (see :data:`EFFECTS` for ranges and defaults)::

    coulomb_friction:Fc            [lbf]       sliding friction; stick-slip (stays stuck while |A·PL| <= Fc)
    viscous_friction:B             [lbf·s/in]  damping beyond the linear model's own B
    valve_saturation:i_max         [mA]        valve current (flow) limit below the DAC limit
    valve_deadband:width           [mA]        spool overlap: no flow for |spool| < width/2
    valve_hysteresis:width         [mA]        backlash-type play: output moves once the input is width/2 away
    pressure_flow_nonlinearity     (none)      orifice law, flow ∝ sqrt((Ps − sign(i)·PL)/Ps); Ps = supply pressure
    sampling_delay:delay           [s]         transport/computation delay beyond the zero-order hold
    valve_dynamics:tau[,order,zeta] [s]        spool lag 1/(tau s + 1), or order=2: wn = 1/tau, damping zeta
    sensor_quantization:bits       [bit]       ADC of the pot voltage, full scale ±10 V (LSB = 20 V / 2**bits)
    sensor_noise:sigma             [in]        white noise on the measured position (the controller sees it)

API::

    effects = EffectSet.parse(["coulomb_friction:Fc=4lbf", "sampling_delay:delay=2ms"])
    effects = EffectSet.from_quantities({"coulomb_friction": {"Fc": "1.2 lbf"}})
    effects.value("coulomb_friction", "Fc")  -> 4.0 (internal units)
    effects.to_quantities()                  -> {"coulomb_friction": {"Fc": "4 lbf"}, ...}
    effects.merged(other)                    -> an effect in both is taken whole from other

Every mistake raises :class:`grader.errors.SimulationError` with a one-line message.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from grader.errors import SimulationError, UnitError
from grader.units import parse_quantity, to_float


@dataclass(frozen=True)
class ParamSpec:
    """One effect parameter: internal unit, default, admissible bounds and typical (realistic) range."""

    name: str
    unit: str
    default: float
    lo: float
    hi: float
    typical: tuple[float, float]
    integer: bool = False


@dataclass(frozen=True)
class EffectSpec:
    """One effect: its parameters and the rationale for their typical ranges."""

    name: str
    params: tuple[ParamSpec, ...]
    rationale: str

    def param(self, name: str) -> ParamSpec:
        for p in self.params:
            if p.name == name:
                return p
        known = ", ".join(p.name for p in self.params) or "none"
        raise SimulationError(f"effect {self.name} has no parameter {name!r} (parameters: {known})")


def _spec(name: str, rationale: str, *params: ParamSpec) -> tuple[str, EffectSpec]:
    return name, EffectSpec(name, params, rationale)


#: The canonical effects, in the order the signal passes through the rig.
EFFECTS: Mapping[str, EffectSpec] = MappingProxyType(dict([
    _spec("sampling_delay", "real-time target I/O and computation: 0 to 3 samples at 1 kHz",
          ParamSpec("delay", "s", 0.001, 0.0, 0.05, (0.0, 0.003))),
    _spec("valve_saturation", "flow or torque-motor current limit, between 40 % and 96 % of the 50 mA amplifier range",
          ParamSpec("i_max", "mA", 40.0, 0.5, 100.0, (20.0, 48.0))),
    _spec("valve_hysteresis", "servo-valve data sheets quote hysteresis of 1 to 5 % of rated current (50 mA)",
          ParamSpec("width", "mA", 1.0, 0.0, 25.0, (0.0, 2.5))),
    _spec("valve_dynamics", "small two-stage flapper-nozzle valves: -90 degree bandwidth 30 to 300 Hz",
          ParamSpec("tau", "s", 0.0015, 0.0, 0.1, (0.0005, 0.005)),
          ParamSpec("order", "dimensionless", 1.0, 1.0, 2.0, (1.0, 2.0), integer=True),
          ParamSpec("zeta", "dimensionless", 0.7, 0.05, 5.0, (0.5, 1.0))),
    _spec("valve_deadband", "spool overlap of a nominally critically lapped valve: 0 to 6 % of rated current",
          ParamSpec("width", "mA", 1.0, 0.0, 25.0, (0.0, 3.0))),
    _spec("pressure_flow_nonlinearity", "orifice law of a critically lapped valve at the station's supply pressure"),
    _spec("coulomb_friction", "seal friction of a 0.5 in bore cylinder: 0.2 to 8 lbf (about 0.1 to 5 % of A·Ps)",
          ParamSpec("Fc", "lbf", 1.0, 0.0, 100.0, (0.2, 8.0))),
    _spec("viscous_friction", "rolling slide and seals: up to about 6 lbf at 4 in/s",
          ParamSpec("B", "lbf*s/in", 0.1, 0.0, 20.0, (0.0, 1.5))),
    _spec("sensor_noise", "pot and wiring noise referred to position: up to 2 mil",
          ParamSpec("sigma", "in", 0.0004, 0.0, 0.1, (0.0, 0.002))),
    _spec("sensor_quantization", "data-acquisition boards of ±10 V span: 12 to 16 bit",
          ParamSpec("bits", "bit", 14.0, 4.0, 24.0, (12.0, 16.0), integer=True)),
]))
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)

_KINDS = {"lbf": "force", "lbf*s/in": "damping coefficient (force·time/length)", "mA": "current",
          "s": "time", "in": "length", "bit": "number of bits"}
_SPEC = re.compile(r"^\s*([A-Za-z_]\w*)\s*(?::(.*))?$")
_PAIR = re.compile(r"^\s*([A-Za-z_]\w*)\s*=\s*(.+?)\s*$")


def effect_spec(name: str) -> EffectSpec:
    """The spec of a canonical effect; unknown names raise with a suggestion."""
    if name in EFFECTS:
        return EFFECTS[name]
    close = difflib.get_close_matches(name, EFFECT_NAMES, n=1)
    hint = f"; did you mean {close[0]}?" if close else ""
    raise SimulationError(f"unknown effect {name!r}{hint} (known: {', '.join(EFFECT_NAMES)})")


def _unit_label(unit: str) -> str:
    return "" if unit == "dimensionless" else f" {unit}"


def parse_param(effect: str, param: str, text: str | float) -> float:
    """One parameter value (a quantity string with units) to an internal float, range-checked."""
    spec = effect_spec(effect).param(param)
    where = f"{effect}:{param}"
    try:
        q = parse_quantity(text, where=where)
        if spec.unit not in ("dimensionless", "bit") and q.unitless and q.magnitude != 0:  # zero is zero in any unit
            raise SimulationError(f"{where}: {text!r} needs a unit, e.g. '{spec.default:g} {spec.unit}'")
        value = to_float(q, spec.unit, where=where) if not q.unitless else float(q.magnitude)
    except UnitError:
        kind = _KINDS.get(spec.unit, "plain number")
        example = f"'{spec.default:g}{_unit_label(spec.unit)}'"
        hint = "; pint reads 'mil' as an angle, write 'thou' or 'in'" if "mil" in str(text) else ""
        raise SimulationError(f"{where}: {text!r} is not a {kind} (e.g. {example}{hint})") from None
    return check_value(effect, param, value)


def check_value(effect: str, param: str, value: float) -> float:
    """Range (and integer) check of an internal value; returns it as a float."""
    spec = effect_spec(effect).param(param)
    where = f"{effect}:{param}"
    if not math.isfinite(value):
        raise SimulationError(f"{where}: value must be finite, got {value}")
    if spec.integer and value != round(value):
        raise SimulationError(f"{where}: must be a whole number, got {value:g}")
    if not spec.lo <= value <= spec.hi:
        unit = _unit_label(spec.unit)
        raise SimulationError(f"{where} = {value:g}{unit} is out of range [{spec.lo:g}, {spec.hi:g}]{unit}")
    return float(value)


def _split(text: str) -> tuple[str, dict[str, str]]:
    """``"name:p=q,p2=q2"`` -> (name, {p: q}); a bare name means the defaults."""
    m = _SPEC.match(text) if isinstance(text, str) else None
    if not m:
        raise SimulationError(f"effect {text!r}: expected 'name' or 'name:param=quantity', e.g. 'coulomb_friction:Fc=4lbf'")
    name, rest = m.group(1), (m.group(2) or "").strip()
    pairs: dict[str, str] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))) if rest else ():
        pm = _PAIR.match(item)
        if not pm:
            raise SimulationError(f"effect {text!r}: {item!r} is not 'param=quantity', e.g. 'Fc=4lbf'")
        if pm.group(1) in pairs:
            raise SimulationError(f"effect {text!r}: parameter {pm.group(1)!r} given twice")
        pairs[pm.group(1)] = pm.group(2)
    return name, pairs


@dataclass(frozen=True)
class EffectSet:
    """Effect name -> {parameter: value in internal units}; every parameter present, all checked."""

    values: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in self.values:
            effect_spec(name)
        clean: dict[str, Mapping[str, float]] = {}
        for name in EFFECT_NAMES:  # canonical order
            if name not in self.values:
                continue
            given = dict(self.values[name])
            spec = EFFECTS[name]
            for p in given:
                spec.param(p)
            clean[name] = MappingProxyType(
                {p.name: check_value(name, p.name, float(given.get(p.name, p.default))) for p in spec.params}
            )
        object.__setattr__(self, "values", MappingProxyType(clean))

    @classmethod
    def parse(cls, specs: Iterable[str]) -> EffectSet:
        """From CLI strings such as ``"coulomb_friction:Fc=4lbf"``; repeats of one effect merge."""
        out: dict[str, dict[str, float]] = {}
        for text in specs:
            name, pairs = _split(text)
            effect_spec(name)
            params = out.setdefault(name, {})
            for p, q in pairs.items():
                if p in params:
                    raise SimulationError(f"effect {name}: parameter {p!r} given twice")
                params[p] = parse_param(name, p, q)
        return cls(out)

    @classmethod
    def from_quantities(cls, mapping: Mapping[str, Mapping[str, str]] | None) -> EffectSet:
        """From ``{name: {param: "quantity"}}`` (station files, ``truth.json``)."""
        out: dict[str, dict[str, float]] = {}
        for name, params in (mapping or {}).items():
            effect_spec(name)
            out[name] = {p: parse_param(name, p, q) for p, q in (params or {}).items()}
        return cls(out)

    def to_quantities(self) -> dict[str, dict[str, str]]:
        """``{name: {param: "value unit"}}``, exact to 12 significant digits (round-trips)."""
        return {
            name: {p: f"{v:.12g}{_unit_label(EFFECTS[name].param(p).unit)}" for p, v in params.items()}
            for name, params in self.values.items()
        }

    def __hash__(self) -> int:
        return hash(tuple((n, tuple(p.items())) for n, p in self.values.items()))

    def __reduce__(self) -> tuple[type[EffectSet], tuple[dict[str, dict[str, float]]]]:
        """Picklable (the read-only views are not): sent to worker processes."""
        return EffectSet, ({n: dict(p) for n, p in self.values.items()},)

    def __contains__(self, name: object) -> bool:
        return name in self.values

    def __bool__(self) -> bool:
        return bool(self.values)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.values)

    def value(self, name: str, param: str) -> float:
        """A parameter of an effect that is on (KeyError if it is off)."""
        return self.values[name][param]

    def merged(self, other: EffectSet) -> EffectSet:
        """These effects with ``other``'s added; an effect in both is taken whole from ``other``."""
        return EffectSet({**self.values, **other.values})

    def without(self, *names: str) -> EffectSet:
        """These effects less ``names``."""
        for name in names:
            effect_spec(name)
        return EffectSet({n: p for n, p in self.values.items() if n not in names})


#: The ideal rig: no effect on.
NO_EFFECTS = EffectSet()
